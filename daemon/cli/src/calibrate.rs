//! `frond calibrate`: measure a user's neutral pose and comfortable ranges (seed 000,
//! section 5.4) from the daemon's raw samples and write a calibration file. The steps and the
//! math are `frond_motion::calibrate`'s (the console's guided calibration uses them too).
//!
//! Each step lasts a few seconds, polling `RawSample` at about 50 Hz.

use std::io::{self, BufRead, IsTerminal};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, anyhow, bail};
use clap::Args;
use frond_formats::rig_toml::CalibrationText;
use frond_motion::calibrate::{Raw, STEPS, compute};
use frond_protocol::{ControlReply, ControlRequest, paths};

use crate::control::Control;
use crate::error::usage;
use crate::global::Global;

/// Poll period for raw samples (about 50 Hz).
const POLL: Duration = Duration::from_millis(20);

/// `frond calibrate` options.
#[derive(Debug, Clone, Args)]
pub struct CalibrateArgs {
    /// Whose calibration this is (the file is named after it).
    #[arg(long, value_name = "NAME")]
    pub user: String,
    /// Seconds for each step.
    #[arg(long, default_value_t = 4.0, value_name = "S")]
    pub seconds_per_step: f64,
    /// Do not wait for Enter before each step.
    #[arg(long)]
    pub yes: bool,
    /// Output file [default: $XDG_CONFIG_HOME/frond/calibrations/NAME.toml].
    #[arg(short = 'o', long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Also apply the new calibration to the running daemon.
    #[arg(long)]
    pub apply: bool,
}

pub(crate) fn run(g: &Global, a: &CalibrateArgs) -> anyhow::Result<()> {
    if let Err(e) = paths::validate_take_name(&a.user) {
        return usage(format!("--user: {}", e.to_string().replace("take name", "user name")));
    }
    if !(a.seconds_per_step.is_finite() && (0.2..=120.0).contains(&a.seconds_per_step)) {
        return usage(format!("--seconds-per-step must be between 0.2 and 120, got {}", a.seconds_per_step));
    }
    let output = match &a.output {
        Some(p) => p.clone(),
        None => {
            // frond's own directory for calibrations is made on first use; a directory given
            // with -o must exist.
            let path = default_calibration_path(&a.user)?;
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
            }
            path
        }
    };
    // Refused before the user performs the steps, not after.
    if let Err(e) = frond_formats::rig_files::output_destination(&output) {
        return usage(format!("cannot write {}: {e}", output.display()));
    }
    let mut control = Control::from_global(g)?;
    let step_len = Duration::from_secs_f64(a.seconds_per_step);
    let tty = io::stdout().is_terminal();
    frond_binmain::outln!(
        "Calibrating {:?}: {} steps of {:.1} s each.",
        a.user,
        STEPS.len(),
        a.seconds_per_step
    )?;
    let mut recorded: Vec<Vec<Raw>> = Vec::with_capacity(STEPS.len());
    for (i, (name, instruction)) in STEPS.iter().enumerate() {
        frond_binmain::outln!("\nStep {}/{} ({name}): {instruction}", i + 1, STEPS.len())?;
        if !a.yes {
            frond_binmain::out!("Press Enter to start... ")?;
            let mut line = String::new();
            if io::stdin().lock().read_line(&mut line)? == 0 {
                bail!("standard input closed while waiting for Enter; use --yes to run without prompts");
            }
        }
        let samples = record_step(&mut control, step_len, tty)?;
        if samples.is_empty() {
            bail!(
                "step {name}: no fresh samples from the device in {:.1} s; check `frond status` \
                 (is the glove connected?)",
                a.seconds_per_step
            );
        }
        frond_binmain::outln!("  {} samples", samples.len())?;
        recorded.push(samples);
    }
    let wrist_steps = [&recorded[1][..], &recorded[2][..], &recorded[3][..]];
    let measured = compute(&a.user, &recorded[0], wrist_steps, &recorded[4])?;
    for w in &measured.warnings {
        frond_binmain::errln!("frond: warning: {w}");
    }
    let cal = measured.calibration;
    let text = format!(
        "# frond calibration for {:?}, written by `frond calibrate` (section 5.4 of \"Interactive authoring of bending and twisting motions of short plants using hand gestures\")\n{}",
        a.user,
        cal.to_toml_string()
    );
    write_atomically(&output, &text)?;
    frond_binmain::outln!("\n{text}\nwrote {}", output.display())?;
    if let Some([[pd, pu], [yd, yu]]) = cal.params().wrist_reach_deg {
        frond_binmain::outln!(
            "comfortable wrist reach from neutral: pitch -{pd:.1} / +{pu:.1}, yaw -{yd:.1} / +{yu:.1} degrees \
             (a rig's bend_range_deg is reached there)"
        )?;
    }
    if a.apply {
        match control.request(&ControlRequest::SetCalibration { id: cal.id.clone(), toml: text })? {
            ControlReply::Ok => frond_binmain::outln!("applied to the running daemon")?,
            _ => bail!("the daemon gave an unexpected reply to SetCalibration"),
        }
    } else {
        frond_binmain::outln!("apply it with: frond calibration apply {}", output.display())?;
    }
    Ok(())
}

/// Polls raw samples for `len`, printing live values on a terminal.
fn record_step(control: &mut Control, len: Duration, tty: bool) -> anyhow::Result<Vec<Raw>> {
    let start = Instant::now();
    let mut next = start;
    let mut out: Vec<Raw> = Vec::new();
    let mut last_print = start;
    while start.elapsed() < len {
        match control.request(&ControlRequest::RawSample)? {
            ControlReply::RawSample { t, wrist_deg, thumb_deg, fresh } => {
                let finite = t.is_finite() && wrist_deg.iter().chain(&thumb_deg).all(|v| v.is_finite());
                let repeated = out.last().is_some_and(|r| r.t == t);
                if fresh && finite && !repeated {
                    out.push(Raw { t, wrist_deg, thumb_deg });
                }
                if tty && last_print.elapsed() >= Duration::from_millis(100) {
                    last_print = Instant::now();
                    let left = len.saturating_sub(start.elapsed()).as_secs_f64();
                    frond_binmain::out!(
                        "\r\x1b[K  wrist p/y/r {:7.1} {:7.1} {:7.1}   thumb {:6.1} {:6.1} {:6.1}   {left:4.1} s left{}",
                        wrist_deg[0],
                        wrist_deg[1],
                        wrist_deg[2],
                        thumb_deg[0],
                        thumb_deg[1],
                        thumb_deg[2],
                        if fresh { "" } else { "  (device not connected)" }
                    )?;
                }
            }
            _ => bail!("the daemon gave an unexpected reply to RawSample"),
        }
        next += POLL;
        if let Some(wait) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        } else {
            next = Instant::now();
        }
    }
    if tty {
        frond_binmain::outln!()?;
    }
    Ok(out)
}

/// `$XDG_CONFIG_HOME/frond/calibrations/NAME.toml`, else `$HOME/.config/...`.
pub(crate) fn default_calibration_path(user: &str) -> anyhow::Result<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME").filter(|v| !v.is_empty()).map(|h| PathBuf::from(h).join(".config"))
        })
        .ok_or_else(|| anyhow!("neither XDG_CONFIG_HOME nor HOME is set; pass -o FILE"))?;
    Ok(base.join("frond").join("calibrations").join(format!("{user}.toml")))
}

/// Writes `text` to `path` via a temporary file in the same directory and a rename.
pub(crate) fn write_atomically(path: &Path, text: &str) -> anyhow::Result<()> {
    write_atomically_bytes(path, text.as_bytes())
}

/// Writes `bytes` to `path` atomically ([`frond_formats::rig_files::write_file_atomically`]).
pub(crate) fn write_atomically_bytes(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    frond_formats::rig_files::write_file_atomically(path, bytes)
        .map_err(|e| anyhow!("cannot write {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_path_follows_xdg() {
        // Only checks the shape: the environment is shared by tests, so it is not modified here.
        let p = default_calibration_path("eve").unwrap();
        assert!(p.ends_with("frond/calibrations/eve.toml"), "{}", p.display());
    }

    #[test]
    fn writes_atomically_into_a_directory_that_exists() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a/b/c.toml");
        // A missing directory is not made (a typo in -o is not a new tree).
        let e = write_atomically(&path, "x = 1\n").unwrap_err().to_string();
        assert!(e.ends_with("a/b does not exist"), "{e}");
        assert!(!dir.path().join("a").exists());
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        write_atomically(&path, "x = 1\n").unwrap();
        write_atomically(&path, "x = 2\n").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "x = 2\n");
        assert_eq!(std::fs::read_dir(path.parent().unwrap()).unwrap().count(), 1);
    }
}
