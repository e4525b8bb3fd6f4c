//! Client of the daemon's control socket, and the one-shot commands built on it
//! (`rig set`, `calibration apply`, `filter`, `mark`, `record start|stop`).

use std::path::Path;

use anyhow::anyhow;
use frond_formats::rig_toml::CalibrationText;
use frond_motion::{Calibration, FilterSpec, Rig};
use frond_protocol::{ControlReply, ControlRequest, RecordingStatus, StatusReport, paths};
use frond_sdk::ControlClient;
use frond_sdk::control_auth::ControlKey;
use frond_sdk::zenoh_control::RemoteControl;

use crate::error::usage;
use crate::global::Global;

/// Largest marker label the daemon accepts, bytes.
const MAX_LABEL_BYTES: usize = 256;

/// One connection to `control.sock` (`frond_sdk::ControlClient`), or to a daemon on another
/// host through its bridge (`--remote`, `frond_sdk::zenoh_control::RemoteControl`), with errors
/// as `anyhow` for the commands.
pub(crate) enum Control {
    /// This host's daemon.
    Local(ControlClient),
    /// Another host's daemon, through its frond-zenoh bridge.
    Remote(Box<RemoteControl>),
}

impl Control {
    /// Connects to the control socket of the daemon in `socket_dir`.
    pub(crate) fn connect(socket_dir: &Path) -> anyhow::Result<Control> {
        Ok(Control::Local(ControlClient::connect(socket_dir)?))
    }

    /// Connects using the global options: the remote daemon `--remote` names, else this host's.
    pub(crate) fn from_global(g: &Global) -> anyhow::Result<Control> {
        let Some(remote) = &g.remote else {
            return Control::connect(&paths::socket_dir(g.socket_dir.clone()));
        };
        let frond_sdk::Source::Zenoh(addr) = remote else {
            return usage(format!(
                "--remote {remote}: a zenoh:frond/<stage>/<source> address (a local daemon needs no --remote)"
            ));
        };
        let (Some(principal), Some(key_file)) = (&g.remote_as, &g.remote_key_file) else {
            return usage(
                "--remote needs --as NAME and --key-file FILE (a principal of the bridge's --control file)",
            );
        };
        let key = match ControlKey::read_file(key_file) {
            Ok(key) => key,
            Err(e) => return usage(e.to_string()),
        };
        Ok(Control::Remote(Box::new(RemoteControl::open(addr, principal, key)?)))
    }

    /// Sends `req` and returns the daemon's reply; a refusal becomes an error with its message.
    /// (A message, not an io::Error: a broken *socket* must not pass for a closed stdout, which
    /// `frond` treats as a quiet success.)
    pub(crate) fn request(&mut self, req: &ControlRequest) -> anyhow::Result<ControlReply> {
        match self {
            Control::Local(c) => c.request(req),
            Control::Remote(c) => c.request(req),
        }
        .map_err(|e| anyhow!("{e}"))
    }

    /// Sends `req` and expects a plain `Ok`.
    pub(crate) fn expect_ok(&mut self, req: &ControlRequest) -> anyhow::Result<()> {
        match self.request(req)? {
            ControlReply::Ok => Ok(()),
            other => Err(unexpected(&other)),
        }
    }

    /// Asks for the daemon's status.
    pub(crate) fn status(&mut self) -> anyhow::Result<StatusReport> {
        match self.request(&ControlRequest::Status)? {
            ControlReply::Status(s) => Ok(*s),
            other => Err(unexpected(&other)),
        }
    }

    /// Starts recording `name`.
    pub(crate) fn record_start(&mut self, name: &str) -> anyhow::Result<RecordingStatus> {
        match self.request(&ControlRequest::RecordStart { name: name.to_string() })? {
            ControlReply::Recording(r) => Ok(r),
            ControlReply::Ok => Ok(RecordingStatus {
                name: name.to_string(),
                path: String::new(),
                frames: 0,
                dropped: 0,
                active: true,
            }),
            other => Err(unexpected(&other)),
        }
    }

    /// Stops the recording.
    pub(crate) fn record_stop(&mut self) -> anyhow::Result<RecordingStatus> {
        match self.request(&ControlRequest::RecordStop)? {
            ControlReply::Recording(r) => Ok(r),
            other => Err(unexpected(&other)),
        }
    }
}

fn unexpected(reply: &ControlReply) -> anyhow::Error {
    let got = frond_sdk::control::reply_kind(reply);
    anyhow!("{}", frond_sdk::ControlClientError::Unexpected { got })
}

/// Reads a text file, naming it in the error.
/// Reads a small regular text file (FIFOs, devices and files over 1 MiB are refused unread).
pub(crate) fn read_text(path: &Path, what: &str) -> anyhow::Result<String> {
    frond_formats::rig_files::read_small_text(path, frond_formats::rig_files::MAX_RIG_FILE_BYTES)
        .map_err(|e| anyhow!("cannot read {what} file {}: {}", path.display(), e.reason()))
}

/// Reads and validates a calibration file.
pub(crate) fn load_calibration(path: &Path) -> anyhow::Result<(Calibration, String)> {
    let text = read_text(path, "calibration")?;
    let cal = Calibration::from_toml_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    Ok((cal, text))
}

/// Reads and validates a rig file (the one rig loader, `frond_formats::rig_files`).
/// A rig given on the command line: an embedded name (`grass`, `flower`, `shrub`) or a rig file,
/// read the way the daemon reads it (`frond_formats::rig_files::load_rig`).
pub(crate) fn load_rig(spec: &Path) -> anyhow::Result<(Rig, String)> {
    let loaded = frond_formats::rig_files::load_rig(&spec.to_string_lossy())?;
    Ok((loaded.rig, loaded.text))
}

/// Parses a filter argument: a full spec, or a bare kind (`lowpass`, `one-euro`) with defaults.
pub(crate) fn parse_filter(spec: &str) -> anyhow::Result<FilterSpec> {
    match spec.trim().parse::<FilterSpec>() {
        Ok(f) => Ok(f),
        Err(e) => usage(format!("--filter {spec:?}: {e}")),
    }
}

pub(crate) fn apply_calibration(g: &Global, file: &Path) -> anyhow::Result<()> {
    let (cal, text) = load_calibration(file)?;
    let mut c = Control::from_global(g)?;
    c.expect_ok(&ControlRequest::SetCalibration { id: cal.id.clone(), toml: text })?;
    frond_binmain::outln!("applied calibration {:?} from {}", cal.id, file.display())?;
    Ok(())
}

pub(crate) fn set_rig(g: &Global, file: &Path) -> anyhow::Result<()> {
    // An embedded name or a file, as `frondd --rig` takes it (the one rig loader).
    let loaded = frond_formats::rig_files::load_rig(&file.to_string_lossy())?;
    // Every rig names itself (validation refuses an empty name): the daemon, status and takes
    // go by that name, whatever the file is called.
    let name = loaded.rig.name.clone();
    let mut c = Control::from_global(g)?;
    c.expect_ok(&ControlRequest::SetRig { name: name.clone(), toml: loaded.text })?;
    frond_binmain::outln!("rig set to {name} ({})", loaded.origin)?;
    Ok(())
}

pub(crate) fn set_filter(g: &Global, spec: &str) -> anyhow::Result<()> {
    let filter = parse_filter(spec)?;
    let mut c = Control::from_global(g)?;
    c.expect_ok(&ControlRequest::SetFilter { spec: filter.to_string() })?;
    frond_binmain::outln!("filter set to {filter}")?;
    Ok(())
}

/// `frond triggers follow|pause`: asks, then says what frondd now does with the stage's starts.
pub(crate) fn set_triggers(g: &Global, follow: bool) -> anyhow::Result<()> {
    let mut c = Control::from_global(g)?;
    c.expect_ok(&ControlRequest::SetTriggers { follow })?;
    let listen = c.status()?.triggers.and_then(|t| t.listen).unwrap_or_default();
    if follow {
        frond_binmain::outln!("following capture triggers on {}", frond_protocol::printable(&listen))?;
    } else {
        frond_binmain::outln!(
            "capture triggers paused: starts heard on {} are counted, not followed (`frond triggers follow` resumes)",
            frond_protocol::printable(&listen)
        )?;
    }
    Ok(())
}

pub(crate) fn mark(g: &Global, label: &str) -> anyhow::Result<()> {
    if label.len() > MAX_LABEL_BYTES {
        return usage(format!("marker label is {} bytes; the limit is {MAX_LABEL_BYTES}", label.len()));
    }
    let mut c = Control::from_global(g)?;
    c.expect_ok(&ControlRequest::Mark { label: label.to_string() })?;
    frond_binmain::outln!("marked {label:?}")?;
    Ok(())
}

pub(crate) fn check_take_name(name: &str) -> anyhow::Result<()> {
    paths::validate_take_name(name).or_else(|e| usage(e.to_string()))
}

pub(crate) fn record_start(g: &Global, name: &str) -> anyhow::Result<()> {
    check_take_name(name)?;
    let mut c = Control::from_global(g)?;
    let r = c.record_start(name)?;
    if r.path.is_empty() {
        frond_binmain::outln!("recording {name}")?;
    } else {
        frond_binmain::outln!("recording {name} to {}", r.path)?;
    }
    Ok(())
}

pub(crate) fn record_stop(g: &Global) -> anyhow::Result<()> {
    let mut c = Control::from_global(g)?;
    let r = c.record_stop()?;
    frond_binmain::outln!("stopped {}: {} frames in {}", r.name, r.frames, r.path)?;
    if r.dropped > 0 {
        frond_binmain::errln!("frond: warning: the recorder dropped {} frames (disk too slow?)", r.dropped);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_sdk::control::not_running_message;
    use std::io;

    /// Issue 18: the hint names only what frond ships (the system unit in /run/frond), not a
    /// user unit that does not exist.
    #[test]
    fn the_not_running_hint_names_what_frond_ships() {
        let err = io::Error::from(io::ErrorKind::NotFound);
        let m = not_running_message(Path::new("/tmp/x/control.sock"), &err);
        assert!(m.contains("no control socket at /tmp/x/control.sock"), "{m}");
        assert!(m.contains("`frondd --socket-dir /tmp/x`") && m.contains("`frond demo`"), "{m}");
        assert!(m.contains("`systemctl start frondd`") && m.contains("FROND_SOCKET_DIR=/run/frond"), "{m}");
        assert!(!m.contains("--user"), "{m}");
        let unit =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../systemd/frondd.service"))
                .expect("the unit the hint names");
        assert!(unit.contains("--socket-dir /run/frond"), "the unit listens where the hint says");
    }

    #[test]
    fn not_running_names_the_socket_and_how_to_start() {
        let e = io::Error::from(io::ErrorKind::NotFound);
        let msg = not_running_message(Path::new("/tmp/x/control.sock"), &e);
        assert!(msg.contains("no control socket at /tmp/x/control.sock"), "{msg}");
        assert!(msg.contains("frondd --socket-dir /tmp/x"), "{msg}");
        let e = io::Error::from(io::ErrorKind::ConnectionRefused);
        let msg = not_running_message(Path::new("/tmp/x/control.sock"), &e);
        assert!(msg.contains("nothing listens on /tmp/x/control.sock"), "{msg}");
    }

    #[test]
    fn bad_take_names_are_usage_errors() {
        let err = check_take_name("../etc").unwrap_err();
        assert!(err.downcast_ref::<crate::error::UsageError>().is_some());
        check_take_name("take_1").unwrap();
    }

    #[test]
    fn a_bad_filter_is_a_usage_error() {
        let err = parse_filter("butterworth").unwrap_err();
        assert!(err.downcast_ref::<crate::error::UsageError>().is_some());
        assert!(err.to_string().contains("butterworth"), "{err}");
    }
}
