//! Issue 18: the shipped `frondd.service` under a real systemd. The machine's own systemd boots
//! as PID 1 of a container the test makes (`systemd_boot.sh`: new PID and mount namespaces on an
//! overlay of / backed by a tmpfs, so nothing reaches the host's files), with the shipped unit and
//! the `frond` group the shipped sysusers file makes, and no `/etc/frond/frondd.toml`. Checked:
//! `systemctl start` returns once frondd said READY=1; it runs as a dynamic user in the `frond`
//! group with the unit's sandbox; a member of the group may use the control socket and an
//! outsider may not; it is not restarted by the watchdog; `systemctl reload` keeps it; a
//! Leap Motion service on loopback reaches it under the unit's network rules (a drop-in changes
//! only the source); `systemctl stop` ends it cleanly.

use std::io::Write;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use frond_e2e::{bin, repo_root, wait_for};

/// The container: its systemd's host pid; killing it ends every process inside.
struct Machine {
    unshare: Child,
    pid: u32,
    _dir: tempfile::TempDir,
}

impl Drop for Machine {
    fn drop(&mut self) {
        // SAFETY: kill(2) on the container's init (our grandchild); harmless if already gone.
        unsafe { libc::kill(self.pid as i32, libc::SIGKILL) };
        let _ = self.unshare.kill();
        let _ = self.unshare.wait();
    }
}

impl Machine {
    /// A command run inside (its mount, PID namespaces and root).
    fn cmd(&self, args: &[&str]) -> Command {
        let mut c = Command::new("nsenter");
        c.args(["-t", &self.pid.to_string(), "-m", "-p", "-r", "-w", "--"]).args(args);
        c
    }

    fn run(&self, args: &[&str]) -> Output {
        self.cmd(args).output().unwrap_or_else(|e| panic!("nsenter {args:?}: {e}"))
    }

    fn ok(&self, args: &[&str]) -> String {
        let out = self.run(args);
        assert!(
            out.status.success(),
            "{args:?}: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// `systemctl show frondd -p NAME --value`.
    fn prop(&self, name: &str) -> String {
        self.ok(&["systemctl", "show", "frondd", "-p", name, "--value"]).trim().to_string()
    }

    /// `frond status --json` inside, as root or through `setpriv ARGS`.
    fn status(&self, setpriv: &[&str]) -> Output {
        let frond = bin("frond");
        let mut args: Vec<&str> = Vec::new();
        if !setpriv.is_empty() {
            args.push("setpriv");
            args.extend(setpriv);
            args.push("--");
        }
        args.extend(["env", "FROND_SOCKET_DIR=/run/frond", frond.to_str().unwrap(), "status", "--json"]);
        self.run(&args)
    }

    /// The process a child of `unshare` became (the container's init).
    fn init_of(unshare: u32) -> Option<u32> {
        let children = std::fs::read_to_string(format!("/proc/{unshare}/task/{unshare}/children")).ok()?;
        children.split_whitespace().next()?.parse().ok()
    }
}

/// Boots the container, or says why it cannot run here (`None`).
fn boot() -> Option<Machine> {
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        return why_not("needs root (namespaces, mounts)");
    }
    if !Path::new("/lib/systemd/systemd").exists() {
        return why_not("no systemd at /lib/systemd/systemd (scripts/test installs the systemd package)");
    }
    for tool in ["unshare", "nsenter", "chroot", "setpriv"] {
        if Command::new(tool).arg("--version").output().is_err() {
            return why_not(&format!("no {tool} (util-linux / coreutils)"));
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let bin_dir = bin("frondd").parent().unwrap().to_path_buf();
    let mut unshare = Command::new("unshare")
        .args(["--mount", "--pid", "--fork", "--uts", "--ipc", "bash"])
        .arg(repo_root().join("tests/e2e/systemd_boot.sh"))
        .arg(dir.path())
        .arg(repo_root())
        .arg(&bin_dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("unshare");
    let deadline = Instant::now() + Duration::from_secs(30);
    let pid = loop {
        if let Some(pid) = Machine::init_of(unshare.id())
            && std::fs::read_to_string(format!("/proc/{pid}/comm")).is_ok_and(|c| c.trim() == "systemd")
        {
            break pid;
        }
        if let Ok(Some(status)) = unshare.try_wait() {
            let mut err = String::new();
            let _ = std::io::Read::read_to_string(&mut unshare.stderr.take().unwrap(), &mut err);
            panic!("the container did not boot ({status}): {err}");
        }
        assert!(Instant::now() < deadline, "systemd did not start in the container within 30 s");
        std::thread::sleep(Duration::from_millis(50));
    };
    let machine = Machine { unshare, pid, _dir: dir };
    let up = wait_for(Duration::from_secs(30), || {
        let state = machine.run(&["systemctl", "is-system-running"]);
        matches!(String::from_utf8_lossy(&state.stdout).trim(), "running" | "degraded")
    });
    assert!(
        up,
        "the container's systemd never finished booting: {}",
        machine.ok(&["systemctl", "--failed", "--no-pager"])
    );
    Some(machine)
}

fn why_not(why: &str) -> Option<Machine> {
    assert!(std::env::var("CI").as_deref() != Ok("true"), "the real-systemd test cannot run in CI: {why}");
    eprintln!("skipped: {why}");
    None
}

#[test]
fn the_shipped_unit_runs_frondd_under_a_real_systemd() {
    let Some(m) = boot() else { return };
    assert!(
        !m.run(&["test", "-e", "/etc/frond/frondd.toml"]).status.success(),
        "a fresh machine has no config"
    );
    m.ok(&["systemctl", "start", "frondd"]);
    assert_eq!(m.prop("ActiveState"), "active");
    assert_eq!(m.prop("SubState"), "running");
    assert!(
        m.prop("StatusText").contains("/run/frond"),
        "READY=1 and STATUS= from frondd: {}",
        m.prop("StatusText")
    );

    // A dynamic user in the `frond` group.
    let pid = m.prop("MainPID");
    let ids = m.ok(&["ps", "-o", "uid=,gid=,user=", "-p", &pid]);
    let cols: Vec<&str> = ids.split_whitespace().collect();
    let frond_gid = m.ok(&["getent", "group", "frond"]).split(':').nth(2).unwrap().trim().to_string();
    assert_ne!(cols[0], "0", "frondd runs as a dynamic user, not root: {ids}");
    assert_eq!(cols[1], frond_gid, "its group is frond: {ids}");

    // The control socket: root, a member of `frond` (its groups read from the socket, which
    // ProtectProc=invisible would hide in /proc), not an outsider.
    let st = m.status(&[]);
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let member = m.status(&["--reuid=4321", "--regid=4321", &format!("--groups={frond_gid}")]);
    assert!(member.status.success(), "a member of frond: {}", String::from_utf8_lossy(&member.stderr));
    let outsider = m.status(&["--reuid=4321", "--regid=4321", "--clear-groups"]);
    assert!(!outsider.status.success(), "an outsider was let in");
    assert!(String::from_utf8_lossy(&outsider.stderr).contains("permission denied"));

    // WatchdogSec=5: fed while the loop ticks, so no restart after longer than that.
    std::thread::sleep(Duration::from_secs(6));
    assert_eq!((m.prop("ActiveState").as_str(), m.prop("NRestarts").as_str()), ("active", "0"));
    // ExecReload sends SIGHUP: the config is re-read, the process stays.
    m.ok(&["systemctl", "reload", "frondd"]);
    assert_eq!((m.prop("ActiveState"), m.prop("MainPID")), ("active".to_string(), pid.clone()));

    // A Leap Motion service on loopback reaches the service (IPAddressAllow=localhost and
    // AF_INET allowed): a drop-in changes only the source, as docs/stage.md's install steps say.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let frames: Vec<String> =
        crate::leap::recorded("finger-tap-54fps.ndjson").iter().map(|f| f.to_string()).collect();
    let stop = Arc::new(AtomicBool::new(false));
    let server = crate::leap::replay_to_each(listener, frames, Arc::clone(&stop));
    let exec = m.prop("ExecStart");
    assert!(exec.contains(&format!("{}/frondd", bin("frondd").parent().unwrap().display())), "{exec}");
    let dropin = format!(
        "[Service]\nExecStart=\nExecStart={} --socket-dir /run/frond --takes-dir /var/lib/frond/takes \
         --config /etc/frond/frondd.toml --config-optional --source leap://127.0.0.1:{port}?hand=right\n",
        bin("frondd").display()
    );
    m.ok(&["mkdir", "-p", "/etc/systemd/system/frondd.service.d"]);
    let mut tee = m
        .cmd(&["tee", "/etc/systemd/system/frondd.service.d/leap.conf"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    tee.stdin.take().unwrap().write_all(dropin.as_bytes()).unwrap();
    assert!(tee.wait().unwrap().success());
    m.ok(&["systemctl", "daemon-reload"]);
    m.ok(&["systemctl", "restart", "frondd"]);
    let leap_reports = || -> u64 {
        let out = m.status(&[]);
        serde_json::from_slice::<serde_json::Value>(&out.stdout)
            .ok()
            .filter(|v| v["source"]["kind"] == "leap")
            .and_then(|v| v["source"]["reports"].as_u64())
            .unwrap_or(0)
    };
    let reached = wait_for(Duration::from_secs(15), || leap_reports() > 0);
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    assert!(
        reached,
        "the service never got a Leap frame over loopback: {}",
        m.ok(&["systemctl", "status", "frondd", "--no-pager", "-n", "20"])
    );

    m.ok(&["systemctl", "stop", "frondd"]);
    assert_eq!((m.prop("ActiveState"), m.prop("Result")), ("inactive".to_string(), "success".to_string()));
}
