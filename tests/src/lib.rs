//! Harness for frond's end-to-end tests: finds the built binaries, starts the virtual glove and
//! the daemon in private directories, and cleans up (kills, unmounts) whatever happens.
//!
//! The binaries are taken from the cargo target directory next to the test executable
//! (`target/<profile>/`), or from `$FROND_BIN_DIR`. `scripts/test` builds them first
//! (`cargo build --workspace --bins`).

#![warn(missing_docs)]

use std::io::{BufRead, BufReader};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use frond_formats::field_json::FieldJson;
use frond_protocol::{ControlReply, ControlRequest, FrameBuf, read_frame, write_frame};

pub use frond_netns as netns;

/// Path of a workspace binary, or a panic that says how to build it.
pub fn bin(name: &str) -> PathBuf {
    let dir = match std::env::var_os("FROND_BIN_DIR") {
        Some(d) => PathBuf::from(d),
        None => {
            let exe = std::env::current_exe().expect("current exe");
            // target/<profile>/deps/<test> -> target/<profile>
            exe.parent().and_then(Path::parent).expect("target dir").to_path_buf()
        }
    };
    let path = dir.join(name);
    assert!(
        path.exists(),
        "{} is missing: build the binaries first with `cargo build --workspace --bins` (scripts/test does)",
        path.display()
    );
    path
}

/// The repository root.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("repo root").to_path_buf()
}

/// True when this machine can mount the virtual glove's FUSE node.
pub fn fuse_available() -> bool {
    Path::new("/dev/fuse").exists()
}

/// A child process killed (SIGTERM, then SIGKILL) when dropped.
pub struct Proc {
    /// The child.
    pub child: Child,
    /// Name for messages.
    pub name: String,
}

impl Proc {
    /// Sends SIGTERM and waits up to `timeout` for exit; returns the exit status if it exited.
    pub fn terminate(&mut self, timeout: Duration) -> Option<std::process::ExitStatus> {
        // SAFETY: kill(2) on our own child's pid; harmless if it already exited.
        unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        None
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait()
            && self.terminate(Duration::from_secs(3)).is_none()
        {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Starts a `frond-zenoh` bridge (`cmd` runs `bin("frond-zenoh")`, here or on a namespace's
/// host) beside `daemon`, publishing it as `frond/<stage>/<source>`; `network` says how it
/// reaches the others (`["--listen", "tcp/ADDR:PORT"]`, `["--connect", .., "--zenoh-config", ..]`).
pub fn start_zenoh_bridge(
    mut cmd: Command,
    daemon: &Daemon,
    stage: &str,
    source: &str,
    network: &[&str],
) -> Proc {
    let child = cmd
        .args(["--stage", stage, "--source", source])
        .args(network)
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .args(["--log-level", "warn"])
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond-zenoh");
    Proc { child, name: format!("frond-zenoh {source}") }
}

/// Starts `frond-vhid` with `args` and waits for the node path it prints first.
pub fn start_vhid(args: &[&str]) -> (Proc, PathBuf, BufReader<std::process::ChildStdout>) {
    let mut child = Command::new(bin("frond-vhid"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond-vhid");
    let mut out = BufReader::new(child.stdout.take().expect("stdout"));
    let mut line = String::new();
    out.read_line(&mut line).expect("read frond-vhid's first line");
    let proc = Proc { child, name: "frond-vhid".into() };
    let node = PathBuf::from(line.trim());
    assert!(!line.trim().is_empty(), "frond-vhid printed no node path");
    (proc, node, out)
}

/// A running `frondd` in private directories.
pub struct Daemon {
    /// The process.
    pub proc: Proc,
    /// Its socket directory.
    pub socket_dir: PathBuf,
    /// Its takes directory.
    pub takes_dir: PathBuf,
}

impl Daemon {
    /// Starts `frondd` with `args` (plus private socket and takes dirs under `root`) and waits
    /// until the control socket answers.
    pub fn start(root: &Path, args: &[&str]) -> Daemon {
        Self::start_with_stderr(root, args, Stdio::inherit())
    }

    /// [`Daemon::start`] with the daemon's log (stderr) going to `stderr`, e.g. a file to read.
    pub fn start_with_stderr(root: &Path, args: &[&str], stderr: Stdio) -> Daemon {
        Self::start_command(Command::new(bin("frondd")), root, args, stderr)
    }

    /// [`Daemon::start`] on another "host": inside `host`'s network namespace.
    pub fn start_on(host: &netns::Host, root: &Path, args: &[&str]) -> Daemon {
        Self::start_command(host.command(bin("frondd")), root, args, Stdio::inherit())
    }

    /// [`Daemon::start`] with `cmd` as the `frondd` command (its environment set, say).
    pub fn start_command(mut cmd: Command, root: &Path, args: &[&str], stderr: Stdio) -> Daemon {
        let socket_dir = root.join("run");
        let takes_dir = root.join("takes");
        let child = cmd
            .arg("--socket-dir")
            .arg(&socket_dir)
            .arg("--takes-dir")
            .arg(&takes_dir)
            .args(args)
            .stdout(Stdio::null())
            .stderr(stderr)
            .spawn()
            .expect("start frondd");
        let mut daemon = Daemon { proc: Proc { child, name: "frondd".into() }, socket_dir, takes_dir };
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            if let Ok(ControlReply::Status(_)) = daemon.try_control(&ControlRequest::Status) {
                return daemon;
            }
            if let Ok(Some(status)) = daemon.proc.child.try_wait() {
                panic!("frondd exited during start-up: {status}");
            }
            assert!(Instant::now() < deadline, "frondd did not answer on its control socket within 20 s");
            std::thread::sleep(Duration::from_millis(25));
        }
    }

    fn try_control(&self, req: &ControlRequest) -> std::io::Result<ControlReply> {
        let mut stream = UnixStream::connect(self.socket_dir.join(frond_protocol::CONTROL_SOCKET))?;
        stream.set_read_timeout(Some(Duration::from_secs(10)))?;
        write_frame(&mut stream, &mut FrameBuf::default(), req)?;
        read_frame(&mut stream, &mut Vec::new()).map_err(|e| std::io::Error::other(e.to_string()))
    }

    /// Sends a control request and returns the reply (panics on transport errors).
    pub fn control(&self, req: &ControlRequest) -> ControlReply {
        self.try_control(req).expect("control request")
    }

    /// The daemon's status.
    pub fn status(&self) -> frond_protocol::StatusReport {
        match self.control(&ControlRequest::Status) {
            ControlReply::Status(s) => *s,
            other => panic!("unexpected status reply {other:?}"),
        }
    }

    /// Runs `frond ARGS` against this daemon; panics with its output unless it succeeds, and
    /// returns its stdout.
    pub fn frond_ok(&self, args: &[&str]) -> String {
        let out = self.frond().args(args).output().expect("run frond");
        assert!(
            out.status.success(),
            "frond {args:?} failed: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// Writes a field of take `take` (`frames` frames at 30 FPS) made with `params` into the
    /// daemon's directory and starts it with `frond field start`, publishing `plants` plants.
    pub fn start_field(
        &self,
        take: &str,
        params: &frond_motion::field::FieldParams,
        frames: usize,
        plants: u16,
    ) {
        let field = frond_motion::field::make_field(params, take, frames, 30.0).expect("make the field");
        let path = self.takes_dir.with_file_name("field.json");
        std::fs::write(&path, field.to_json()).expect("write field.json");
        let plants = plants.to_string();
        self.frond_ok(&[
            "field",
            "start",
            "--take",
            take,
            "--field",
            path.to_str().unwrap(),
            "--plants",
            &plants,
        ]);
    }

    /// A `frond` command pointed at this daemon.
    pub fn frond(&self) -> Command {
        let mut cmd = Command::new(bin("frond"));
        cmd.env("FROND_SOCKET_DIR", &self.socket_dir).env("FROND_TAKES_DIR", &self.takes_dir);
        cmd
    }
}

/// Waits until `cond` holds or `timeout` passes; returns whether it held.
pub fn wait_for(timeout: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    cond()
}

/// Sends one `/frond/hand` message per `(t, wrist pitch)` to `127.0.0.1:port` (the other five
/// angles 0), `gap` apart, as a tracker would.
pub fn send_osc_pitches(port: u16, samples: &[(f64, f32)], gap: Duration) {
    use rosc::{OscMessage, OscPacket, OscType};
    let tx = std::net::UdpSocket::bind("127.0.0.1:0").expect("a UDP socket");
    for &(t, pitch) in samples {
        let mut args = vec![OscType::Double(t), OscType::Float(pitch)];
        args.extend([0.0f32; 5].map(OscType::Float));
        let packet = OscPacket::Message(OscMessage { addr: "/frond/hand".into(), args });
        tx.send_to(&rosc::encoder::encode(&packet).expect("encodable"), ("127.0.0.1", port))
            .expect("send to the daemon's OSC port");
        std::thread::sleep(gap);
    }
}

/// The next `n` poses of `sub` that carry a new report (not flagged `held`), waiting at most
/// `timeout`: fewer when they do not come.
pub fn fresh_poses(sub: &mut frond_sdk::Subscriber, n: usize, timeout: Duration) -> Vec<frond_sdk::Pose> {
    let mut fresh = Vec::new();
    let deadline = Instant::now() + timeout;
    while fresh.len() < n && Instant::now() < deadline {
        if let frond_sdk::Event::Pose(p) = sub.next_event().expect("the pose stream")
            && !p.flags.contains(frond_protocol::PoseFlags::HELD)
        {
            fresh.push(p);
        }
    }
    fresh
}

/// `frond map ARGS` with `input` on its standard input, run to the end.
pub fn frond_map(args: &[&str], input: &str) -> std::process::Output {
    use std::io::Write;
    let mut map = Command::new(bin("frond"))
        .arg("map")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start frond map");
    // A refusal may close stdin before all of it is read: that is frond map's answer, not ours.
    let _ = map.stdin.take().expect("stdin").write_all(input.as_bytes());
    map.wait_with_output().expect("frond map")
}
