//! `frond demo`: start `frondd` on the virtual glove with a private socket directory, show live
//! status and a few poses, record a take, bake it and render a preview of the whole take, say
//! where they are, then leave the daemon and the console running (the plant moving live) until
//! Ctrl-C or `--stay SECONDS`, and stop everything.
//!
//! The daemon runs in its own process group (so the terminal's Ctrl-C reaches only `frond`,
//! which then stops the recording and the daemon in order) with `PR_SET_PDEATHSIG` set to
//! SIGTERM (so even a `kill -9` of `frond` takes the daemon down). A drop guard sends SIGTERM,
//! waits, and falls back to SIGKILL on every exit path, errors included.

use std::fs::File;
use std::io::{self, IsTerminal};
use std::os::unix::net::UnixStream;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant, SystemTime};

use anyhow::{Context, anyhow, bail};
use frond_protocol::{CONTROL_SOCKET, POSES_SOCKET, PoseFlags, paths};
use frond_sdk::{Event, SdkError, Subscriber};

use crate::control::{Control, check_take_name};
use crate::error::{Interrupted, usage};
use crate::global::Global;
use crate::{signals, tap};

/// How long the daemon gets to create its sockets.
const READY_TIMEOUT: Duration = Duration::from_secs(20);
/// How long the daemon gets to exit after SIGTERM before SIGKILL.
const STOP_TIMEOUT: Duration = Duration::from_secs(5);
/// Poses printed before recording starts.
const TAP_LINES: usize = 3;

/// Longest `--stay`, seconds (a day).
const MAX_STAY_S: f64 = 86_400.0;

pub(crate) fn run(g: &Global, seconds: f64, name: Option<String>, stay: Option<f64>) -> anyhow::Result<()> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 3600.0) {
        return usage(format!("--seconds must be greater than 0 and at most 3600, got {seconds}"));
    }
    if let Some(s) = stay
        && !(s.is_finite() && (0.0..=MAX_STAY_S).contains(&s))
    {
        return usage(format!("--stay must be 0 to {MAX_STAY_S} seconds, got {s}"));
    }
    let name = name.unwrap_or_else(|| {
        let now = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
        format!("demo-{now}")
    });
    check_take_name(&name)?;
    let frondd = find_program("frondd")?;
    let takes_dir = paths::takes_dir(g.takes_dir.clone());
    std::fs::create_dir_all(&takes_dir)
        .with_context(|| format!("cannot create the takes directory {}", takes_dir.display()))?;
    let socket_dir = tempfile::Builder::new()
        .prefix("frond-demo-")
        .tempdir()
        .context("cannot create a private socket directory")?;
    signals::install().context("installing signal handlers")?;

    frond_binmain::outln!("starting {} (sockets in {})", frondd.display(), socket_dir.path().display())?;
    let mut daemon = Daemon::spawn(&frondd, socket_dir.path(), &takes_dir)?;
    daemon.wait_ready()?;
    let console = start_console(socket_dir.path(), &takes_dir);
    if let Some((_, url)) = &console {
        frond_binmain::outln!(
            "console:    {url}  (the plant live in 3D, health and takes; open it while the demo runs)"
        )?;
    }
    let result = demo_session(&mut daemon, socket_dir.path(), &takes_dir, &name, seconds).and_then(|take| {
        report_take(&take, &name, &takes_dir)?;
        stay_live(&mut daemon, console.as_ref().map(|(_, url)| url.as_str()), socket_dir.path(), stay)
    });
    drop(console);
    let stopped = daemon.stop();
    match (&result, stopped) {
        (_, Ok(status)) if !status.success() => {
            frond_binmain::errln!(
                "frond: warning: frondd exited with {status}; its log:\n{}",
                daemon.log_tail()
            )
        }
        (_, Err(e)) => frond_binmain::errln!("frond: warning: stopping frondd: {e:#}"),
        _ => frond_binmain::outln!("daemon and console stopped")?,
    }
    result
}

/// Says where the take is, bakes it and renders its preview (the daemon still running, so the
/// console stays live meanwhile).
fn report_take(take: &TakeResult, name: &str, takes_dir: &Path) -> anyhow::Result<()> {
    frond_binmain::outln!()?;
    frond_binmain::outln!("take {name}: {} frames in {}", take.frames, take.path)?;
    match bake_glb(&take.path, "grass") {
        Ok(glb) => frond_binmain::outln!(
            "baked:      {} (skinned, animated glTF 2.0 for Blender, Maya, Unreal, Unity, three.js)",
            glb.display()
        )?,
        Err(e) => frond_binmain::errln!("frond: warning: no GLB baked: {e:#}"),
    }
    match warp_preview(&take.path) {
        Ok((gif, frames, fps)) => frond_binmain::outln!(
            "preview:    {} (grass blown by the take's wind, frond-warp: the whole take, {frames} frames at {fps} fps)",
            gif.display()
        )?,
        Err(e) => frond_binmain::errln!("frond: warning: no warp preview: {e:#}"),
    }
    let td = takes_dir.display();
    frond_binmain::outln!("export it:  frond take export {name} --jsonl --takes-dir {td} > {name}.jsonl")?;
    frond_binmain::outln!(
        "at 30 fps:  frond take export {name} --jsonl --fps 30 --takes-dir {td} > {name}-30fps.jsonl"
    )?;
    frond_binmain::outln!("list takes: frond take list --takes-dir {td}")?;
    Ok(())
}

/// Keeps the daemon (and the console, when it started) running after the take, so the newcomer
/// has the plant moving live to look at: until Ctrl-C, or `stay` seconds (0: not at all). A
/// Ctrl-C here is the normal end of the demo, not an interruption.
fn stay_live(
    daemon: &mut Daemon,
    url: Option<&str>,
    socket_dir: &Path,
    stay: Option<f64>,
) -> anyhow::Result<()> {
    let limit = stay.map(Duration::from_secs_f64);
    if limit.is_some_and(|l| l.is_zero()) {
        return Ok(());
    }
    let until = match stay {
        Some(s) => format!("for {s} s (Ctrl-C ends it sooner)"),
        None => "until Ctrl-C".to_string(),
    };
    frond_binmain::outln!()?;
    match url {
        Some(url) => {
            frond_binmain::outln!("live:       {url}  the plant moves on the virtual glove {until}")?
        }
        None => frond_binmain::outln!(
            "live:       the daemon runs on the virtual glove {until}: FROND_SOCKET_DIR={} frond tap",
            socket_dir.display()
        )?,
    }
    let start = Instant::now();
    loop {
        if signals::interrupted() {
            frond_binmain::outln!()?;
            return Ok(());
        }
        if let Some(status) = daemon.try_wait()? {
            bail!("frondd exited unexpectedly ({status}); its log:\n{}", daemon.log_tail());
        }
        if limit.is_some_and(|l| start.elapsed() >= l) {
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

struct TakeResult {
    path: String,
    frames: u64,
}

fn demo_session(
    daemon: &mut Daemon,
    socket_dir: &Path,
    takes_dir: &Path,
    name: &str,
    seconds: f64,
) -> anyhow::Result<TakeResult> {
    let mut control = Control::connect(socket_dir)?;
    let st = control.status()?;
    frond_binmain::outln!(
        "frondd {} running: source {} {} ({}), rig {}, filter {}, {} Hz",
        st.daemon_version,
        st.source.kind,
        st.source.path,
        if st.source.connected { "connected" } else { "not connected yet" },
        st.rig_name,
        st.filter,
        st.tick_rate_hz
    )?;
    let mut sub = Subscriber::options()
        .reconnect(false)
        .read_timeout(Some(Duration::from_millis(200)))
        .connect(socket_dir)?;
    let names = sub.hello().joint_names.clone();

    // A few live poses.
    let mut shown = 0;
    let mut line = String::new();
    let deadline = Instant::now() + Duration::from_secs(5);
    while shown < TAP_LINES && Instant::now() < deadline {
        check_interrupt(daemon)?;
        match next_event(&mut sub)? {
            Some(Event::Pose(p)) if !p.flags.contains(PoseFlags::HELD) => {
                line.clear();
                tap::pose_human(&p, &names, &mut line);
                frond_binmain::outln!("{line}")?;
                shown += 1;
            }
            _ => {}
        }
    }

    let rec = control.record_start(name)?;
    if !rec.path.is_empty() {
        frond_binmain::outln!("recording {name} to {} for {seconds} s", rec.path)?;
    }
    let tty = io::stdout().is_terminal();
    let start = Instant::now();
    let length = Duration::from_secs_f64(seconds);
    let mut next_status = start;
    let outcome = (|| -> anyhow::Result<()> {
        while start.elapsed() < length {
            check_interrupt(daemon)?;
            let _ = next_event(&mut sub)?;
            if Instant::now() >= next_status {
                let st = control.status()?;
                let stats = sub.stats();
                let frames = st.recording.as_ref().map(|r| r.frames).unwrap_or(0);
                let text = format!(
                    "REC {name} {:>5.1}/{seconds:.1}s | {} frames | {:.1} Hz of {} | late p99 {:.0} us max {:.0} us | \
                     received {} gaps {} | source {}",
                    start.elapsed().as_secs_f64().min(seconds),
                    frames,
                    st.achieved_rate_hz,
                    st.tick_rate_hz,
                    st.lateness.p99_us,
                    st.lateness.max_us,
                    stats.frames,
                    stats.gaps,
                    if st.source.connected { "connected" } else { "LOST" },
                );
                if tty {
                    frond_binmain::out!("\r\x1b[K{text}")?;
                    next_status += Duration::from_millis(250);
                } else {
                    frond_binmain::outln!("{text}")?;
                    next_status += Duration::from_secs(1);
                }
            }
        }
        Ok(())
    })();
    if tty {
        frond_binmain::outln!()?;
    }
    // Stop the recording whatever happened, so the take is closed properly.
    let stop = control.record_stop();
    outcome?;
    let stopped = stop?;
    let path = if stopped.path.is_empty() {
        takes_dir.join(format!("{name}.take")).display().to_string()
    } else {
        stopped.path
    };
    Ok(TakeResult { path, frames: stopped.frames })
}

fn check_interrupt(daemon: &mut Daemon) -> anyhow::Result<()> {
    if signals::interrupted() {
        return Err(Interrupted.into());
    }
    if let Some(status) = daemon.try_wait()? {
        bail!("frondd exited unexpectedly ({status}); its log:\n{}", daemon.log_tail());
    }
    Ok(())
}

/// One event, or `None` after a read timeout.
fn next_event(sub: &mut Subscriber) -> anyhow::Result<Option<Event>> {
    match sub.next_event() {
        Ok(Event::Disconnected) => bail!("the daemon closed the pose stream"),
        Ok(ev) => Ok(Some(ev)),
        Err(SdkError::Timeout { .. }) => Ok(None),
        Err(e) => Err(e.into()),
    }
}

/// A frond program (`frondd`, `frond-gltf`, ...) next to this executable, else on `PATH`.
pub(crate) fn find_program(name: &str) -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("cannot find the frond executable's path")?;
    let beside = exe.with_file_name(name);
    if is_executable(&beside) {
        return Ok(beside);
    }
    if let Some(path) = std::env::var_os("PATH") {
        for dir in std::env::split_paths(&path) {
            let candidate = dir.join(name);
            if is_executable(&candidate) {
                return Ok(candidate);
            }
        }
    }
    Err(anyhow!(
        "cannot find {name}: not at {} and not on PATH (build it with `cargo build --release --workspace --bins`)",
        beside.display()
    ))
}

/// Largest preview, frames: at 30 fps, 30 s of take; a longer take is rendered at a lower rate
/// (at least 1 fps), still whole.
const PREVIEW_MAX_FRAMES: f64 = 900.0;

/// The preview's frame count and rate for a take `duration_s` long: every instant of it, at
/// 30 fps while that is at most [`PREVIEW_MAX_FRAMES`] frames, else at the rate that fits (at
/// least 1 fps).
fn preview_frames(duration_s: f64) -> (u32, f64) {
    let duration_s = if duration_s.is_finite() { duration_s.max(0.0) } else { 0.0 };
    let fps =
        if duration_s > 0.0 { (PREVIEW_MAX_FRAMES / duration_s).clamp(1.0, 30.0).floor() } else { 30.0 };
    // Frame k shows t = k / fps: frames 0..=n cover 0..=duration.
    let frames = (duration_s * fps).ceil() + 1.0;
    (frames.min(100_000.0) as u32, fps)
}

/// Renders a picture of grass blowing in the take's wind with `frond-warp` (seed 001), the whole
/// take ([`preview_frames`]): the sample pictures are drawn by `frond-warp make-samples`, so the
/// demo needs no files from the source tree. Returns the GIF, its frames and rate.
fn warp_preview(take_path: &str) -> anyhow::Result<(PathBuf, u32, f64)> {
    let bytes = std::fs::read(take_path).with_context(|| format!("cannot read {take_path}"))?;
    let scan = frond_formats::take::scan_take(&bytes).map_err(|e| anyhow!("{take_path}: {e}"))?;
    let (frames, fps) = preview_frames(scan.duration_s());
    let (frames_arg, fps_arg) = (frames.to_string(), fps.to_string());
    let warp = find_program("frond-warp")?;
    let samples = tempfile::Builder::new().prefix("frond-demo-images-").tempdir()?;
    let run = |args: &[&std::ffi::OsStr]| -> anyhow::Result<()> {
        let status = Command::new(&warp)
            .args(args)
            .stdout(Stdio::null())
            .status()
            .with_context(|| format!("cannot run {}", warp.display()))?;
        if !status.success() {
            return Err(anyhow!("{} exited with {status}", warp.display()));
        }
        Ok(())
    };
    run(&["make-samples".as_ref(), samples.path().as_os_str()])?;
    let out = Path::new(take_path).with_extension("gif");
    let (image, mask) = (samples.path().join("grass.png"), samples.path().join("grass-mask.png"));
    run(&[
        "render".as_ref(),
        "--quiet".as_ref(),
        "--image".as_ref(),
        image.as_os_str(),
        "--layer".as_ref(),
        mask.as_os_str(),
        "--take".as_ref(),
        take_path.as_ref(),
        "--frames".as_ref(),
        frames_arg.as_ref(),
        "--fps".as_ref(),
        fps_arg.as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ])?;
    Ok((out, frames, fps))
}

/// Bakes the demo take into a GLB beside it with `frond-gltf`, so the animator can open it at once.
fn bake_glb(take_path: &str, rig: &str) -> anyhow::Result<PathBuf> {
    let gltf = find_program("frond-gltf")?;
    let out = Path::new(take_path).with_extension("glb");
    let status = Command::new(&gltf)
        .args(["bake", "--quiet", "--rig", rig, "--take", take_path, "-o"])
        .arg(&out)
        .stdout(Stdio::null())
        .status()
        .with_context(|| format!("cannot run {}", gltf.display()))?;
    if !status.success() {
        return Err(anyhow!("{} bake exited with {status}", gltf.display()));
    }
    Ok(out)
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

/// A program `frond demo` started: in its own process group (the terminal's Ctrl-C reaches only
/// `frond`), with `PR_SET_PDEATHSIG` (it dies with `frond`), stopped on drop.
struct Managed {
    child: Child,
    name: &'static str,
    exited: Option<ExitStatus>,
}

impl Managed {
    fn spawn(name: &'static str, mut cmd: Command) -> anyhow::Result<Managed> {
        cmd.process_group(0);
        // SAFETY: the closure runs in the forked child before exec and only calls prctl(2),
        // which is async-signal-safe, and allocates nothing.
        unsafe {
            cmd.pre_exec(|| {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM as libc::c_ulong) != 0 {
                    return Err(io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child =
            cmd.spawn().with_context(|| format!("cannot start {}", cmd.get_program().to_string_lossy()))?;
        Ok(Managed { child, name, exited: None })
    }

    fn try_wait(&mut self) -> io::Result<Option<ExitStatus>> {
        if self.exited.is_none() {
            self.exited = self.child.try_wait()?;
        }
        Ok(self.exited)
    }

    /// SIGTERM, wait up to [`STOP_TIMEOUT`], then SIGKILL.
    fn stop(&mut self) -> anyhow::Result<ExitStatus> {
        if let Some(status) = self.try_wait()? {
            return Ok(status);
        }
        let pid = self.child.id() as libc::pid_t;
        // SAFETY: kill(2) on our own child's pid, which has not been reaped (try_wait above
        // returned None), so the pid cannot have been reused.
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let start = Instant::now();
        while start.elapsed() < STOP_TIMEOUT {
            if let Some(status) = self.try_wait()? {
                return Ok(status);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        frond_binmain::errln!("frond: {} ignored SIGTERM for {STOP_TIMEOUT:?}; killing it", self.name);
        self.child.kill()?;
        let status = self.child.wait()?;
        self.exited = Some(status);
        Ok(status)
    }
}

impl Drop for Managed {
    fn drop(&mut self) {
        if let Err(e) = self.stop() {
            frond_binmain::errln!("frond: could not stop {} (pid {}): {e:#}", self.name, self.child.id());
        }
    }
}

/// The child daemon; stopped on drop.
struct Daemon {
    process: Managed,
    socket_dir: PathBuf,
    log_path: PathBuf,
}

impl Daemon {
    fn spawn(frondd: &Path, socket_dir: &Path, takes_dir: &Path) -> anyhow::Result<Daemon> {
        let log_path = socket_dir.join("frondd.log");
        let log = File::create(&log_path).with_context(|| format!("cannot create {}", log_path.display()))?;
        let mut cmd = Command::new(frondd);
        cmd.arg("--socket-dir")
            .arg(socket_dir)
            .arg("--takes-dir")
            .arg(takes_dir)
            .arg("--log-level")
            .arg("info")
            .env_remove(paths::SOCKET_DIR_ENV)
            .env_remove(paths::TAKES_DIR_ENV)
            .stdin(Stdio::null())
            .stdout(log.try_clone()?)
            .stderr(log);
        let process = Managed::spawn("frondd", cmd)?;
        Ok(Daemon { process, socket_dir: socket_dir.to_owned(), log_path })
    }

    fn try_wait(&mut self) -> io::Result<Option<ExitStatus>> {
        self.process.try_wait()
    }

    fn stop(&mut self) -> anyhow::Result<ExitStatus> {
        self.process.stop()
    }

    /// Waits until both sockets accept connections.
    fn wait_ready(&mut self) -> anyhow::Result<()> {
        let start = Instant::now();
        loop {
            check_interrupt(self)?;
            let control = UnixStream::connect(self.socket_dir.join(CONTROL_SOCKET));
            if control.is_ok() && self.socket_dir.join(POSES_SOCKET).exists() {
                return Ok(());
            }
            if start.elapsed() > READY_TIMEOUT {
                bail!(
                    "frondd did not open {} within {READY_TIMEOUT:?}; its log:\n{}",
                    self.socket_dir.join(CONTROL_SOCKET).display(),
                    self.log_tail()
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The last lines of the daemon's log, for error messages.
    fn log_tail(&self) -> String {
        let text = std::fs::read_to_string(&self.log_path).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        let tail = &lines[lines.len().saturating_sub(20)..];
        if tail.is_empty() { "  (empty)".into() } else { tail.iter().map(|l| format!("  {l}\n")).collect() }
    }
}

/// The console beside the demo's daemon (`frond-console`), on 127.0.0.1:8790 if free, else on
/// a port the system picks; returns it with the URL it printed. `None` (after saying why) when
/// it is not installed or does not start: the demo goes on without it.
fn start_console(socket_dir: &Path, takes_dir: &Path) -> Option<(Managed, String)> {
    let program = match find_program("frond-console") {
        Ok(p) => p,
        Err(e) => {
            frond_binmain::errln!("frond: note: no console: {e:#}");
            return None;
        }
    };
    for listen in ["127.0.0.1:8790", "127.0.0.1:0"] {
        let mut cmd = Command::new(&program);
        cmd.arg("--socket-dir")
            .arg(socket_dir)
            .arg("--takes-dir")
            .arg(takes_dir)
            .args(["--listen", listen])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null());
        let Ok(mut console) = Managed::spawn("frond-console", cmd) else { continue };
        let mut line = String::new();
        let read = console
            .child
            .stdout
            .take()
            .map(|out| io::BufRead::read_line(&mut io::BufReader::new(out), &mut line));
        if let (Some(Ok(n)), Some(url)) = (read, line.strip_prefix("frond-console: "))
            && n > 0
        {
            let url = url.split_whitespace().next().unwrap_or_default().to_string();
            return Some((console, url));
        }
    }
    frond_binmain::errln!("frond: note: frond-console did not start; the demo goes on without it");
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_preview_covers_the_whole_take() {
        // 5 s at 30 fps: t = 0, 1/30, ..., 5 s is 151 frames (the old preview stopped at 45).
        assert_eq!(preview_frames(5.0), (151, 30.0));
        assert_eq!(preview_frames(1.5), (46, 30.0));
        // 60 s: 900 / 60 = 15 fps, 901 frames.
        assert_eq!(preview_frames(60.0), (901, 15.0));
        // An hour: 1 fps, 3601 frames.
        assert_eq!(preview_frames(3600.0), (3601, 1.0));
        assert_eq!(preview_frames(0.0), (1, 30.0));
        assert_eq!(preview_frames(f64::NAN), (1, 30.0));
    }
}
