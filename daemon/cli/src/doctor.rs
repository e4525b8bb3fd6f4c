//! `frond doctor [--json]`: checks what a stage set-up needs and explains each problem with its
//! fix: the daemon and its socket directory, the glove's hidraw node and its permissions, the udev
//! rule and the `frond` group, FUSE for the virtual glove, realtime limits, the service's state,
//! and the exporters: installed beside `frond`, able to subscribe as this user, connected now
//! (named by process), their services. Exit status 0 when nothing needs fixing, 1 otherwise.

use std::path::{Path, PathBuf};

use frond_protocol::{ControlReply, ControlRequest, paths};
use serde::Serialize;

use crate::control::Control;
use crate::global::Global;

/// The glove the udev rule and the default device profile name (pid.codes).
const GLOVE_HID_ID: &str = "00001209:0000F0D1";
/// Where the udev rule is installed.
const UDEV_RULES: [&str; 2] = ["/etc/udev/rules.d/70-frond.rules", "/lib/udev/rules.d/70-frond.rules"];

/// How one check went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// Fine.
    Ok,
    /// Works, but not as well as it could (a fallback is used).
    Warn,
    /// Needs fixing for a stage.
    Problem,
}

/// One check: what was found and, unless it is fine, how to fix it.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// Short name (`daemon`, `glove`, ...).
    pub name: &'static str,
    /// The verdict.
    pub verdict: Verdict,
    /// What was found.
    pub found: String,
    /// What to do, when something is to be done.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix: Option<String>,
}

fn check(name: &'static str, verdict: Verdict, found: String, fix: Option<String>) -> Check {
    Check { name, verdict, found, fix }
}

/// The daemon, and what its status says needs the operator (`frond_sdk::health`, as the
/// console shows it): one check each.
fn daemon(dir: &Path, status: &anyhow::Result<ControlReply>) -> Vec<Check> {
    match status {
        Ok(ControlReply::Status(s)) => {
            let mut out = vec![check(
                "daemon",
                Verdict::Ok,
                format!(
                    "frondd {} at {} ({} source {}, {} subscribers)",
                    s.daemon_version,
                    dir.display(),
                    s.source.kind,
                    s.source.path,
                    s.subscribers.len()
                ),
                None,
            )];
            out.extend(
                frond_sdk::health::problems(s)
                    .into_iter()
                    .map(|p| check("stage", Verdict::Problem, p.what, Some(p.fix))),
            );
            out
        }
        Ok(other) => vec![check("daemon", Verdict::Problem, format!("unexpected reply {other:?}"), None)],
        Err(e) => vec![check(
            "daemon",
            Verdict::Problem,
            format!("no daemon answers at {}", dir.display()),
            Some(frond_binmain::error_text(e.as_ref())),
        )],
    }
}

fn socket_dir(dir: &Path) -> Check {
    use std::os::unix::fs::MetadataExt;
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => {
            // SAFETY: getuid has no preconditions.
            let me = unsafe { libc::getuid() };
            let mode = m.mode() & 0o777;
            let verdict = if m.uid() == me || me == 0 { Verdict::Ok } else { Verdict::Warn };
            let fix = (verdict != Verdict::Ok).then(|| {
                format!("{} belongs to uid {}; run as that user or pass --socket-dir", dir.display(), m.uid())
            });
            check(
                "socket-dir",
                verdict,
                format!("{} (mode {mode:o}, owner uid {})", dir.display(), m.uid()),
                fix,
            )
        }
        Ok(_) => check(
            "socket-dir",
            Verdict::Problem,
            format!("{} is not a directory", dir.display()),
            Some("remove it, or pass --socket-dir DIR (env FROND_SOCKET_DIR)".to_string()),
        ),
        Err(_) => check(
            "socket-dir",
            Verdict::Warn,
            format!("{} does not exist yet", dir.display()),
            Some("frondd creates it when it starts".into()),
        ),
    }
}

/// The hidraw nodes and whether one is the glove (HID_ID in sysfs) and openable.
fn glove() -> Check {
    let mut nodes = Vec::new();
    if let Ok(rd) = std::fs::read_dir("/sys/class/hidraw") {
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let uevent = std::fs::read_to_string(e.path().join("device/uevent")).unwrap_or_default();
            let id = uevent.lines().find_map(|l| l.strip_prefix("HID_ID=")).unwrap_or("").to_string();
            nodes.push((PathBuf::from("/dev").join(&name), id));
        }
    }
    nodes.sort();
    let gloves: Vec<&(PathBuf, String)> = nodes.iter().filter(|(_, id)| id.ends_with(GLOVE_HID_ID)).collect();
    let Some((node, id)) = gloves.first() else {
        return check(
            "glove",
            Verdict::Warn,
            format!("no frond glove among {} hidraw nodes", nodes.len()),
            Some(
                "plug the glove in (USB or Bluetooth), or use the virtual glove (`frondd --source virtual`)"
                    .into(),
            ),
        );
    };
    let bus = if id.starts_with("0005:") { "Bluetooth" } else { "USB" };
    match std::fs::OpenOptions::new().read(true).write(true).open(node) {
        Ok(_) => check("glove", Verdict::Ok, format!("{} ({bus}) opens read-write", node.display()), None),
        Err(e) => check(
            "glove",
            Verdict::Problem,
            format!("{} ({bus}) cannot be opened: {e}", node.display()),
            Some(
                "install the udev rule and join the frond group (see `udev` and `group`), then replug".into(),
            ),
        ),
    }
}

fn udev_rule() -> Check {
    match UDEV_RULES.iter().find(|p| Path::new(p).is_file()) {
        Some(p) => check("udev", Verdict::Ok, format!("{p} installed"), None),
        None => check(
            "udev",
            Verdict::Warn,
            "the udev rule is not installed: only root can open the glove".into(),
            Some(
                "sudo cp systemd/70-frond.rules /etc/udev/rules.d/ && sudo udevadm control --reload && sudo udevadm trigger"
                    .into(),
            ),
        ),
    }
}

fn group() -> Check {
    let name = std::ffi::CString::new("frond").expect("no NUL");
    // SAFETY: getgrnam with a valid C string; the result is read at once.
    let gr = unsafe { libc::getgrnam(name.as_ptr()) };
    if gr.is_null() {
        return check(
            "group",
            Verdict::Warn,
            "there is no `frond` group".into(),
            Some("sudo groupadd --system frond && sudo usermod -aG frond $USER (then log in again)".into()),
        );
    }
    // SAFETY: `gr` is a valid group entry returned just above.
    let gid = unsafe { (*gr).gr_gid };
    let mut groups = vec![0 as libc::gid_t; 256];
    // SAFETY: the buffer holds `groups.len()` entries.
    let n = unsafe { libc::getgroups(groups.len() as i32, groups.as_mut_ptr()) };
    // SAFETY: getuid/getgid have no preconditions.
    let (uid, egid) = unsafe { (libc::getuid(), libc::getegid()) };
    let member = egid == gid || (n > 0 && groups[..n as usize].contains(&gid));
    if member || uid == 0 {
        check(
            "group",
            Verdict::Ok,
            format!("in group frond (gid {gid}){}", if uid == 0 { " or root" } else { "" }),
            None,
        )
    } else {
        check(
            "group",
            Verdict::Problem,
            format!("not in group frond (gid {gid}): the glove and the control socket refuse this user"),
            Some("sudo usermod -aG frond $USER (then log in again)".into()),
        )
    }
}

fn fuse() -> Check {
    match std::fs::OpenOptions::new().read(true).write(true).open("/dev/fuse") {
        Ok(_) => check(
            "fuse",
            Verdict::Ok,
            "/dev/fuse opens: the virtual glove can serve a hidraw node".into(),
            None,
        ),
        Err(e) => check(
            "fuse",
            Verdict::Warn,
            format!("/dev/fuse: {e}: the virtual glove runs in-process only"),
            Some("install fuse3 (`apt install fuse3`) for the virtual glove's hidraw node".into()),
        ),
    }
}

fn realtime() -> Check {
    let limit = |res| {
        let mut r = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
        // SAFETY: getrlimit writes one rlimit into `r`.
        unsafe { libc::getrlimit(res, &mut r) };
        r.rlim_cur
    };
    let (rtprio, memlock) = (limit(libc::RLIMIT_RTPRIO), limit(libc::RLIMIT_MEMLOCK));
    // SAFETY: getuid has no preconditions.
    let root = unsafe { libc::getuid() } == 0;
    let found = format!(
        "RLIMIT_RTPRIO {}, RLIMIT_MEMLOCK {}",
        rtprio,
        if memlock == libc::RLIM_INFINITY {
            "unlimited".to_string()
        } else {
            format!("{} KiB", memlock / 1024)
        }
    );
    if root || rtprio > 0 {
        check("realtime", Verdict::Ok, found, None)
    } else {
        check(
            "realtime",
            Verdict::Warn,
            format!("{found}: realtime.priority needs RLIMIT_RTPRIO > 0 (the loop runs at normal priority)"),
            Some(
                "run frondd from the unit (LimitRTPRIO=, LimitMEMLOCK= are set there) or add `@frond - rtprio 90` and `@frond - memlock unlimited` to /etc/security/limits.d/frond.conf"
                    .into(),
            ),
        )
    }
}

fn service() -> Check {
    let out = std::process::Command::new("systemctl").args(["is-active", "frondd"]).output();
    match out {
        Err(_) => check("service", Verdict::Warn, "no systemctl here".into(), None),
        Ok(o) => {
            let state = String::from_utf8_lossy(&o.stdout).trim().to_string();
            if state == "active" {
                check("service", Verdict::Ok, "frondd.service is active".into(), None)
            } else {
                check(
                    "service",
                    Verdict::Warn,
                    format!("frondd.service is {}", if state.is_empty() { "unknown" } else { &state }),
                    Some(
                        "install the unit (systemd/frondd.service) and `systemctl enable --now frondd`"
                            .into(),
                    ),
                )
            }
        }
    }
}

/// The exporters a stage uses, beside `frond` or on PATH.
const EXPORTERS: [&str; 5] = ["frond-gltf", "frond-osc", "frond-warp", "frond-console", "frond-zenoh"];

/// The exporters: installed; able to reach the daemon (this user may subscribe to its pose
/// socket: an exporter run as this user can); which are connected now (the daemon's subscribers,
/// named by their process); and the state of any `frond-exporter@` service.
fn exporters(dir: &Path, status: &anyhow::Result<ControlReply>) -> Vec<Check> {
    let here = std::env::current_exe().ok().and_then(|p| p.parent().map(Path::to_path_buf));
    let on_path = |name: &str| {
        here.as_ref().is_some_and(|d| d.join(name).is_file())
            || std::env::var_os("PATH")
                .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()))
    };
    let missing: Vec<&str> = EXPORTERS.into_iter().filter(|n| !on_path(n)).collect();
    let mut out = vec![if missing.is_empty() {
        check("exporters", Verdict::Ok, format!("{} are installed", EXPORTERS.join(", ")), None)
    } else {
        check(
            "exporters",
            Verdict::Warn,
            format!("not found beside frond or on PATH: {}", missing.join(", ")),
            Some("install them with frond (`cargo install --path exporters/<name>`)".into()),
        )
    }];
    if let Ok(ControlReply::Status(s)) = status {
        out.push(reachable(dir, s));
    }
    out.extend(exporter_units());
    out
}

/// Whether an exporter run as this user reaches the daemon: a subscription to the pose socket
/// gets its hello. Lists the subscribers connected now by process name.
fn reachable(dir: &Path, s: &frond_protocol::StatusReport) -> Check {
    let connected: Vec<String> = s
        .subscribers
        .iter()
        .map(|sub| {
            let name = (sub.pid != 0)
                .then(|| std::fs::read_to_string(format!("/proc/{}/comm", sub.pid)).ok())
                .flatten()
                .map(|n| n.trim().to_string())
                .unwrap_or_else(|| "a subscriber".into());
            let dropped =
                if sub.dropped > 0 { format!(", {} frames dropped", sub.dropped) } else { String::new() };
            format!("{name} (pid {}{dropped})", sub.pid)
        })
        .collect();
    let now = if connected.is_empty() {
        "none connected now".to_string()
    } else {
        format!("connected: {}", connected.join(", "))
    };
    match frond_sdk::Subscriber::options().read_timeout(Some(std::time::Duration::from_secs(2))).connect(dir)
    {
        Ok(_) => check(
            "reach",
            Verdict::Ok,
            format!("exporters run as you can subscribe at {}; {now}", dir.display()),
            None,
        ),
        Err(e) => {
            let fix = match &e {
                frond_sdk::SdkError::Refused { .. } => format!(
                    "raise `max_subscribers` under [publisher] in the daemon's config (now {} connected), or stop a subscriber that is not needed",
                    s.subscribers.len()
                ),
                frond_sdk::SdkError::NotRunning { source, .. }
                    if source.kind() == std::io::ErrorKind::PermissionDenied =>
                {
                    "join the daemon's group (`sudo usermod -aG frond $USER`, then log in again) or run the exporter as the daemon's user".into()
                }
                _ => "see the daemon check above; `frond status` shows the publisher's state".into(),
            };
            check(
                "reach",
                Verdict::Problem,
                format!(
                    "an exporter run as you cannot subscribe at {}: {}",
                    dir.display(),
                    frond_binmain::error_text(&e)
                ),
                Some(fix),
            )
        }
    }
}

/// Installed `frond-exporter@NAME` services: a failed one is a problem, with where its log is.
fn exporter_units() -> Vec<Check> {
    let Ok(out) = std::process::Command::new("systemctl")
        .args(["list-units", "frond-exporter@*", "--all", "--plain", "--no-legend", "--no-pager"])
        .output()
    else {
        return Vec::new();
    };
    if !out.status.success() {
        return Vec::new();
    }
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|line| {
            let mut cols = line.split_whitespace();
            let (unit, _load, active, sub) = (cols.next()?, cols.next()?, cols.next()?, cols.next()?);
            Some(match active {
                "active" => check("exporter", Verdict::Ok, format!("{unit} is {sub}"), None),
                "failed" => check(
                    "exporter",
                    Verdict::Problem,
                    format!("{unit} failed"),
                    Some(format!("see `journalctl -u {unit}`, then `systemctl restart {unit}`")),
                ),
                other => check(
                    "exporter",
                    Verdict::Warn,
                    format!("{unit} is {other}"),
                    Some(format!("`systemctl start {unit}`")),
                ),
            })
        })
        .collect()
}

/// Every check, in order.
pub fn checks(g: &Global) -> Vec<Check> {
    let dir = paths::socket_dir(g.socket_dir.clone());
    let status = Control::connect(&dir).and_then(|mut c| c.request(&ControlRequest::Status));
    let mut all = daemon(&dir, &status);
    all.extend([socket_dir(&dir), glove(), udev_rule(), group(), fuse(), realtime(), service()]);
    all.extend(exporters(&dir, &status));
    all
}

/// Runs `frond doctor`; `Ok(false)` when something needs fixing.
pub(crate) fn run(g: &Global, json: bool) -> anyhow::Result<bool> {
    let all = checks(g);
    let healthy = all.iter().all(|c| c.verdict != Verdict::Problem);
    if json {
        frond_binmain::outln!("{}", serde_json::json!({ "healthy": healthy, "checks": all }))?;
    } else {
        frond_binmain::out!("{}", render(&all, healthy))?;
    }
    Ok(healthy)
}

/// The readable report: a line per check (and one per fix), then the verdict. What a check
/// found quotes the daemon's report (versions, paths, names, problems), so it is escaped
/// ([`frond_protocol::printable`]): none of it can draw a line of its own.
fn render(all: &[Check], healthy: bool) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    for c in all {
        let mark = match c.verdict {
            Verdict::Ok => "ok     ",
            Verdict::Warn => "warn   ",
            Verdict::Problem => "PROBLEM",
        };
        let _ = writeln!(o, "{mark} {:<10} {}", c.name, frond_protocol::printable(&c.found));
        if let Some(fix) = &c.fix {
            let _ = writeln!(o, "        {:<10} fix: {}", "", frond_protocol::printable(fix));
        }
    }
    let _ = writeln!(
        o,
        "{}",
        if healthy { "nothing needs fixing" } else { "something needs fixing (PROBLEM above)" }
    );
    o
}

#[cfg(test)]
mod render_tests {
    use super::*;

    #[test]
    fn what_a_check_found_cannot_draw_a_line_of_its_own() {
        let fake = "frondd 1\nok      glove      fine\u{1b}[1A".to_string();
        let all = [check("daemon", Verdict::Problem, fake.clone(), Some(fake))];
        let t = render(&all, false);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(
            lines,
            [
                "PROBLEM daemon     frondd 1\\nok      glove      fine\\u{1b}[1A",
                "                   fix: frondd 1\\nok      glove      fine\\u{1b}[1A",
                "something needs fixing (PROBLEM above)",
            ]
        );
    }
}
