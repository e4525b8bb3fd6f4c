//! Child processes (frondd, frond-vhid, exporters), where their binaries are, and what /proc says
//! about them and the machine.

use std::io::{BufRead, BufReader};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

use frond_protocol::{ControlReply, ControlRequest, FrameBuf, read_frame, write_frame};

use crate::Options;
use crate::error::BenchError;
use crate::report::Machine;

/// Directory of the workspace's binaries.
pub fn bin_dir(o: &Options) -> PathBuf {
    if let Some(d) = &o.bin_dir {
        return d.clone();
    }
    if let Some(d) = std::env::var_os("FROND_BIN_DIR") {
        return PathBuf::from(d);
    }
    let exe = std::env::current_exe().unwrap_or_default();
    let dir = exe.parent().map(Path::to_path_buf).unwrap_or_default();
    // A test executable lives in target/<profile>/deps.
    if dir.ends_with("deps") { dir.parent().map(Path::to_path_buf).unwrap_or(dir) } else { dir }
}

/// Path of binary `name`, or why it is not there.
pub fn find_bin(o: &Options, name: &str) -> Result<PathBuf, BenchError> {
    let p = bin_dir(o).join(name);
    if p.is_file() { Ok(p) } else { Err(BenchError::NotBuilt(p)) }
}

/// A child process, terminated (SIGTERM, then SIGKILL) when dropped.
pub struct Proc {
    /// The child.
    pub child: Child,
}

impl Proc {
    /// Its pid.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            // SAFETY: kill(2) on our own child's pid.
            unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
            let deadline = Instant::now() + Duration::from_secs(3);
            while Instant::now() < deadline {
                if let Ok(Some(_)) = self.child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Starts `frond-vhid` with `args`; returns it and the node path it prints first.
pub fn start_vhid(o: &Options, args: &[&str]) -> Result<(Proc, PathBuf, BufReader<ChildStdout>), BenchError> {
    let mut child = Command::new(find_bin(o, "frond-vhid")?)
        .args(args)
        .arg("--log-level")
        .arg("warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(BenchError::start("frond-vhid"))?;
    let mut out = BufReader::new(child.stdout.take().ok_or(BenchError::NoPipe("frond-vhid has no stdout"))?);
    let proc = Proc { child };
    let mut line = String::new();
    out.read_line(&mut line).map_err(|source| BenchError::Read { what: "frond-vhid's node path", source })?;
    if line.trim().is_empty() {
        return Err(BenchError::NoNodePath);
    }
    Ok((proc, PathBuf::from(line.trim()), out))
}

/// A running `frondd` in private directories.
pub struct Daemon {
    /// The process.
    pub proc: Proc,
    /// Its socket directory.
    pub socket_dir: PathBuf,
    _dir: tempfile::TempDir,
}

impl Daemon {
    /// Starts `frondd` with `args` and waits until its control socket answers.
    pub fn start(o: &Options, args: &[&str]) -> Result<Daemon, BenchError> {
        Self::start_with_env(o, args, &[])
    }

    /// [`Daemon::start`] with environment variables set for `frondd` (`FROND_HANDS`).
    pub fn start_with_env(
        o: &Options,
        args: &[&str],
        env: &[(&str, &std::ffi::OsStr)],
    ) -> Result<Daemon, BenchError> {
        let dir = tempfile::Builder::new().prefix("frond-bench-").tempdir()?;
        let socket_dir = dir.path().join("run");
        let child = Command::new(find_bin(o, "frondd")?)
            .arg("--socket-dir")
            .arg(&socket_dir)
            .arg("--takes-dir")
            .arg(dir.path().join("takes"))
            .args(["--log-level", "warn"])
            .args(args)
            .envs(env.iter().copied())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(BenchError::start("frondd"))?;
        let mut d = Daemon { proc: Proc { child }, socket_dir, _dir: dir };
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            if let Ok(ControlReply::Status(_)) = d.control(&ControlRequest::Status) {
                return Ok(d);
            }
            if let Ok(Some(status)) = d.proc.child.try_wait() {
                return Err(BenchError::DaemonExited(status));
            }
            if Instant::now() > deadline {
                return Err(BenchError::DaemonSilent);
            }
            std::thread::sleep(Duration::from_millis(25));
        }
    }

    /// One control request.
    pub fn control(&self, req: &ControlRequest) -> Result<ControlReply, BenchError> {
        let mut s = UnixStream::connect(self.socket_dir.join(frond_protocol::CONTROL_SOCKET))?;
        s.set_read_timeout(Some(Duration::from_secs(10)))?;
        write_frame(&mut s, &mut FrameBuf::default(), req)?;
        Ok(read_frame(&mut s, &mut Vec::new())?)
    }

    /// The daemon's status.
    pub fn status(&self) -> Result<frond_protocol::StatusReport, BenchError> {
        match self.control(&ControlRequest::Status)? {
            ControlReply::Status(s) => Ok(*s),
            other => Err(BenchError::UnexpectedReply(format!("{other:?}"))),
        }
    }

    /// Path of poses.sock.
    pub fn poses_socket(&self) -> PathBuf {
        self.socket_dir.join(frond_protocol::POSES_SOCKET)
    }
}

/// Nanoseconds every thread of process `pid` has run on a CPU (sum of
/// `/proc/PID/task/*/schedstat`); threads that ended are not counted.
pub fn process_cpu_ns(pid: u32) -> Result<u64, BenchError> {
    let dir = format!("/proc/{pid}/task");
    let mut total = 0u64;
    for entry in std::fs::read_dir(&dir).map_err(BenchError::at(&dir))? {
        let path = entry?.path().join("schedstat");
        if let Ok(text) = std::fs::read_to_string(&path) {
            total += text.split_whitespace().next().and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
        }
    }
    Ok(total)
}

/// A `kB` field of `/proc/PID/status` (`VmRSS`, `VmHWM`), in bytes.
pub fn status_kb(pid: u32, field: &str) -> Result<u64, BenchError> {
    let path = format!("/proc/{pid}/status");
    let text = std::fs::read_to_string(&path).map_err(BenchError::at(&path))?;
    text.lines()
        .find_map(|l| l.strip_prefix(field).and_then(|r| r.strip_prefix(':')))
        .and_then(|v| v.split_whitespace().next()?.parse::<u64>().ok())
        .map(|kb| kb * 1024)
        .ok_or_else(|| BenchError::ProcField { path, field: field.into() })
}

/// The machine, for the report header.
pub fn machine(realtime: String) -> Machine {
    let nproc = std::thread::available_parallelism().map_or(1, |n| n.get());
    let cpu_model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines().find_map(|l| {
                l.strip_prefix("model name").map(|r| r.trim_start_matches([' ', '\t', ':']).to_string())
            })
        })
        .unwrap_or_else(|| "unknown".into());
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease")
        .map(|s| s.trim().to_string())
        .unwrap_or_default();
    let load_avg_1m = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0.0);
    Machine { nproc, cpu_model, kernel, load_avg_1m, realtime }
}
