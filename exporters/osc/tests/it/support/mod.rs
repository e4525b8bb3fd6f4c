//! Helpers shared by frond-osc's end-to-end tests (`e2e.rs`, `blender.rs`): the daemon on the
//! virtual glove, a `frond_sdk` collector beside the exporter, frond-osc and Python receivers as
//! child processes.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use frond_protocol::{Hello, Pose};
use frond_sdk::{SdkError, Subscriber};

pub fn frond_osc() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_frond-osc"))
}

pub fn frondd() -> Option<PathBuf> {
    let dir = match std::env::var_os("FROND_BIN_DIR") {
        Some(d) => PathBuf::from(d),
        None => frond_osc().parent()?.to_path_buf(),
    };
    Some(dir.join("frondd")).filter(|p| p.exists())
}

#[path = "../../../../../tests/support/field_socket.rs"]
pub mod field_socket;
#[path = "../../../../../tests/support/python.rs"]
mod support_python;
pub use support_python::{python_with, skip};

pub fn python() -> Option<PathBuf> {
    python_with("pythonosc")
}

/// Kills (SIGTERM, then SIGKILL) and reaps the child when dropped.
pub struct Proc(pub Child);

impl Proc {
    pub fn terminate(&mut self) -> Option<std::process::ExitStatus> {
        // SAFETY: kill(2) on our own child's pid; harmless if it already exited (not yet reaped).
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(s)) = self.0.try_wait() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        None
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Ok(None) = self.0.try_wait()
            && self.terminate().is_none()
        {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
}

pub struct Daemon {
    _proc: Proc,
    pub socket_dir: PathBuf,
    pub takes_dir: PathBuf,
    _dir: tempfile::TempDir,
}

/// `frondd --source in-process` (the built-in virtual glove) on the grass rig.
pub fn start_daemon(frondd: &Path) -> Daemon {
    start_daemon_with(frondd, &["--source", "in-process"])
}

/// `frondd ARGS` in a fresh socket and takes directory.
pub fn start_daemon_with(frondd: &Path, args: &[&str]) -> Daemon {
    let dir = tempfile::tempdir().unwrap();
    let socket_dir = dir.path().join("run");
    let child = Command::new(frondd)
        .arg("--socket-dir")
        .arg(&socket_dir)
        .arg("--takes-dir")
        .arg(dir.path().join("takes"))
        .args(args)
        .args(["--log-level", "warn"])
        .stdout(Stdio::null())
        .spawn()
        .expect("start frondd");
    let mut proc = Proc(child);
    let deadline = Instant::now() + Duration::from_secs(20);
    while Subscriber::connect(&socket_dir).is_err() {
        if let Ok(Some(status)) = proc.0.try_wait() {
            panic!("frondd exited during start-up: {status}");
        }
        assert!(Instant::now() < deadline, "frondd's pose socket did not come up within 20 s");
        std::thread::sleep(Duration::from_millis(25));
    }
    Daemon { _proc: proc, socket_dir, takes_dir: dir.path().join("takes"), _dir: dir }
}

/// A `frond_sdk` subscriber collecting every pose until stopped.
pub struct Collector {
    stop: Arc<AtomicBool>,
    handle: JoinHandle<(Hello, Vec<Pose>)>,
}

impl Collector {
    pub fn start(socket_dir: &Path) -> Collector {
        let mut sub = Subscriber::options()
            .read_timeout(Some(Duration::from_millis(200)))
            .connect(socket_dir)
            .expect("sdk subscriber");
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let handle = std::thread::spawn(move || {
            let mut poses = Vec::new();
            while !flag.load(Ordering::Relaxed) {
                match sub.next() {
                    Some(Ok(p)) => poses.push(p),
                    Some(Err(SdkError::Timeout { .. })) => {}
                    Some(Err(e)) => panic!("sdk subscriber: {e}"),
                    None => break,
                }
            }
            (sub.hello().clone(), poses)
        });
        Collector { stop, handle }
    }

    pub fn finish(self) -> (Hello, Vec<Pose>) {
        self.stop.store(true, Ordering::Relaxed);
        self.handle.join().expect("collector thread")
    }
}

/// Starts the Python receiver; returns it and the UDP port it printed.
pub fn start_receiver(py: &Path, mode: &str, count: usize, out: &Path) -> (Proc, u16) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/osc_receiver.py");
    let mut child = Command::new(py)
        .arg(script)
        .args(["--mode", mode, "--count", &count.to_string(), "--timeout", "60", "--out"])
        .arg(out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the python receiver");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).expect("receiver port");
    let port = line.trim().parse().unwrap_or_else(|_| panic!("receiver printed `{line}`, not a port"));
    (Proc(child), port)
}

pub fn start_osc(socket_dir: &Path, args: &[&str]) -> Proc {
    let child = Command::new(frond_osc())
        .arg("--socket-dir")
        .arg(socket_dir)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start frond-osc");
    Proc(child)
}

/// Waits for the receiver to finish; panics with its stderr unless it succeeded.
pub fn wait_receiver(receiver: &mut Proc) {
    let deadline = Instant::now() + Duration::from_secs(90);
    let status = loop {
        if let Some(s) = receiver.0.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "the python receiver did not finish within 90 s");
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut err = String::new();
    receiver.0.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert!(status.success(), "the python receiver failed ({status}): {err}");
}

pub fn read_jsonl(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).expect("receiver wrote JSON"))
        .collect()
}

pub fn f32s(v: &serde_json::Value) -> Vec<f32> {
    v.as_array().expect("array").iter().map(|x| x.as_f64().expect("number") as f32).collect()
}

pub fn stop_and_stderr(mut proc: Proc) -> String {
    let status = proc.terminate();
    assert!(status.is_some(), "frond-osc did not exit on SIGTERM");
    let mut err = String::new();
    proc.0.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert!(status.unwrap().success(), "frond-osc exited with {status:?}: {err}");
    err
}
