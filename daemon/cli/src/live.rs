//! Live modes of the daemon (seed 000, sections 5.3 and 6.2-6.4): looped playback, layered
//! recording, field playback and its keyboard controls, guided motion.

use std::io::{self, BufRead, IsTerminal, Read, Write};
use std::path::Path;

use frond_protocol::control::StageKind;
use frond_protocol::{ControlReply, ControlRequest, RecordingStatus, StageInput, StageKey, StageSpec};

use crate::control::{Control, check_take_name};
use crate::global::Global;

pub(crate) fn play(g: &Global, take: Option<String>, stop: bool, seed: u64) -> anyhow::Result<()> {
    if !stop && take.is_none() {
        return crate::error::usage("frond play needs a TAKE or --stop");
    }
    if let Some(t) = &take {
        check_take_name(t)?;
    }
    let mut c = Control::from_global(g)?;
    let req = match &take {
        Some(t) => {
            ControlRequest::StageStart { name: None, spec: StageSpec::Playback { take: t.clone(), seed } }
        }
        None => ControlRequest::StageStop { name: "playback".into() },
    };
    c.expect_ok(&req)?;
    match take {
        Some(t) => {
            frond_binmain::outln!("looping take {t} on the pose stream (element 0, flagged playback)")?;
            warn_damaged_stage(&mut c, "playback");
        }
        None => frond_binmain::outln!("playback stopped")?,
    }
    Ok(())
}

/// Says on stderr when the daemon reports that the take a stage just started from is damaged
/// (it plays the readable frames; `frond take repair` rewrites the take without the rest).
fn warn_damaged_stage(c: &mut Control, stage: &str) {
    let Ok(status) = c.status() else { return };
    if let Some(s) = status.stages.iter().find(|s| s.name == stage)
        && s.state.contains("(damaged:")
    {
        frond_binmain::errln!("frond: warning: {}", s.state);
    }
}

pub(crate) fn record_layer(
    g: &Global,
    name: &str,
    layer: &str,
    over: Option<String>,
    seed: u64,
) -> anyhow::Result<()> {
    check_take_name(name)?;
    if let Some(t) = &over {
        check_take_name(t)?;
    }
    let mut c = Control::from_global(g)?;
    let req = ControlRequest::RecordLayer {
        name: name.into(),
        layer: layer.into(),
        global_take: over.clone(),
        seed,
    };
    match c.request(&req)? {
        ControlReply::Recording(RecordingStatus { path, .. }) => {
            frond_binmain::outln!("recording layer {layer} as take {name} to {path}")?;
            if let Some(t) = over {
                frond_binmain::outln!("looping {t} meanwhile; `frond record stop` ends both")?;
            }
            Ok(())
        }
        other => Err(anyhow::anyhow!("unexpected reply {other:?}")),
    }
}

/// What `frond field start` asks for besides the take and the field file.
pub(crate) struct FieldStart<'a> {
    /// Plants announced as `field-plant` elements (1..=64).
    pub plants: u16,
    /// Seed of the loop's random jumps.
    pub seed: u64,
    /// The plants' rig: an embedded rig's name or a rig file; `None`: the active rig.
    pub rig: Option<&'a Path>,
    /// The stage's name (`field` when none): fields under different names run side by side.
    pub name: Option<&'a str>,
}

pub(crate) fn field_start(g: &Global, take: &str, field: &Path, ask: FieldStart) -> anyhow::Result<()> {
    check_take_name(take)?;
    let FieldStart { plants, seed, rig, name } = ask;
    if !(1..=64).contains(&plants) {
        return crate::error::usage(format!("--plants must be 1..=64, got {plants}"));
    }
    if let Some(n) = name {
        check_stage_name(n)?;
    }
    let rig_toml = rig.map(field_rig_text).transpose()?;
    // The daemon takes it in one control request: no larger than that.
    let rig_bytes = rig_toml.as_ref().map_or(0, |t| t.len() as u64);
    let max = frond_protocol::MAX_CONTROL_REQUEST as u64 - 4096 - rig_bytes;
    let field_json = frond_formats::rig_files::read_small_text(field, max).map_err(|e| {
        let too_big = matches!(e, frond_formats::rig_files::FileError::TooLarge { .. });
        let hint = if too_big {
            " (write it with `frond take field --compact`, which leaves the plants out: the daemon makes them from the parameters)"
        } else {
            ""
        };
        anyhow::anyhow!("cannot read field file {}: {}{hint}", field.display(), e.reason())
    })?;
    let mut c = Control::from_global(g)?;
    let spec = match rig_toml {
        None => StageSpec::Field { take: take.into(), field_json, plants, seed },
        Some(rig_toml) => StageSpec::FieldOfRig { take: take.into(), field_json, plants, seed, rig_toml },
    };
    c.expect_ok(&ControlRequest::StageStart { name: name.map(str::to_string), spec })?;
    let stage = name.unwrap_or("field");
    let named = name.map(|n| format!(" {n}")).unwrap_or_default();
    let of_rig = rig.map(|r| format!(" of rig {}", r.display())).unwrap_or_default();
    frond_binmain::outln!(
        "field{named} of take {take}{of_rig} playing; steer it with `frond control` or a wrist swipe"
    )?;
    warn_damaged_stage(&mut c, stage);
    Ok(())
}

/// The text of rig `spec` (an embedded rig's name or a rig file) for a field's plants, at most
/// [`frond_protocol::MAX_STAGE_RIG_BYTES`]; the daemon checks the rest.
fn field_rig_text(spec: &Path) -> anyhow::Result<String> {
    let loaded = frond_formats::rig_files::load_rig(&spec.to_string_lossy())?;
    let max = frond_protocol::MAX_STAGE_RIG_BYTES;
    if loaded.text.len() > max {
        anyhow::bail!("rig {}: {} bytes; a field's rig is at most {max}", loaded.origin, loaded.text.len());
    }
    Ok(loaded.text)
}

/// Refuses a stage name the daemon would refuse, before anything is read.
fn check_stage_name(name: &str) -> anyhow::Result<()> {
    let plain = !name.is_empty()
        && name.len() <= 32
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    if plain {
        Ok(())
    } else {
        crate::error::usage(format!(
            "--name {:?}: a stage name is 1 to 32 letters, digits, '-' or '_'",
            name.chars().take(40).collect::<String>()
        ))
    }
}

/// The fields `name` picks: that one, or every field running (a meadow of several rigs is
/// several fields, steered as one); `field`, the default name, when none runs, so that the
/// daemon's answer says so.
fn fields_named(c: &mut Control, name: Option<&str>) -> anyhow::Result<Vec<String>> {
    if let Some(n) = name {
        check_stage_name(n)?;
        return Ok(vec![n.to_string()]);
    }
    let status = c.status()?;
    let names: Vec<String> = status
        .stages
        .iter()
        .filter(|s| s.kind == StageKind::Field.as_str())
        .map(|s| s.name.clone())
        .collect();
    Ok(if names.is_empty() { vec!["field".into()] } else { names })
}

pub(crate) fn field_stop(g: &Global, name: Option<&str>) -> anyhow::Result<()> {
    let mut c = Control::from_global(g)?;
    for n in fields_named(&mut c, name)? {
        c.expect_ok(&ControlRequest::StageStop { name: n.clone() })?;
        frond_binmain::outln!(
            "{} stopped",
            if n == "field" { "field playback".to_string() } else { format!("field {n}") }
        )?;
    }
    Ok(())
}

/// Sends key `key` to the fields `name` picks ([`fields_named`]; a usage error names the keys).
fn send_key(c: &mut Control, key: &str, name: Option<&str>) -> anyhow::Result<()> {
    let key: StageKey = match key.parse() {
        Ok(k) => k,
        Err(e) => return crate::error::usage(e.to_string()),
    };
    for n in fields_named(c, name)? {
        c.expect_ok(&ControlRequest::StageInput { name: n, input: StageInput::Key(key) })?;
    }
    Ok(())
}

pub(crate) fn field_key(g: &Global, key: &str, name: Option<&str>) -> anyhow::Result<()> {
    let mut c = Control::from_global(g)?;
    send_key(&mut c, key, name)?;
    print_field_state(&mut c)
}

fn print_field_state(c: &mut Control) -> anyhow::Result<()> {
    if let ControlReply::Status(s) = c.request(&ControlRequest::Status)? {
        for m in s.modes.iter().filter(|m| m.starts_with("field")) {
            frond_binmain::outln!("{m}")?;
        }
    }
    Ok(())
}

pub(crate) fn guided(g: &Global, spec: &str) -> anyhow::Result<()> {
    let spec = (spec != "off").then(|| spec.to_string());
    let req = match &spec {
        Some(s) => ControlRequest::StageStart { name: None, spec: StageSpec::Guided { spec: s.clone() } },
        None => ControlRequest::StageStop { name: "guided".into() },
    };
    Control::from_global(g)?.expect_ok(&req)?;
    match spec {
        Some(s) => frond_binmain::outln!("guided motion on: {s}")?,
        None => frond_binmain::outln!("guided motion off")?,
    }
    Ok(())
}

/// Puts the terminal in raw mode for the guard's lifetime.
struct RawMode {
    saved: libc::termios,
}

impl RawMode {
    fn enter() -> Option<RawMode> {
        // SAFETY: termios is plain data; tcgetattr fills it for fd 0 or fails.
        let mut t: libc::termios = unsafe { std::mem::zeroed() };
        // SAFETY: fd 0 and a valid termios pointer.
        if unsafe { libc::tcgetattr(0, &mut t) } != 0 {
            return None;
        }
        let saved = t;
        t.c_lflag &= !(libc::ICANON | libc::ECHO);
        t.c_cc[libc::VMIN] = 1;
        t.c_cc[libc::VTIME] = 0;
        // SAFETY: fd 0 and a valid termios.
        if unsafe { libc::tcsetattr(0, libc::TCSANOW, &t) } != 0 {
            return None;
        }
        Some(RawMode { saved })
    }
}

impl Drop for RawMode {
    fn drop(&mut self) {
        // SAFETY: restores the settings read in `enter`.
        unsafe { libc::tcsetattr(0, libc::TCSANOW, &self.saved) };
    }
}

/// Maps terminal bytes to key names: arrows (ESC [ A..D), + / =, -, q.
fn keys_from_bytes(bytes: &[u8]) -> Vec<&'static str> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            0x1b if bytes.get(i + 1) == Some(&b'[') && i + 2 < bytes.len() => {
                match bytes[i + 2] {
                    b'A' => out.push("up"),
                    b'B' => out.push("down"),
                    b'C' => out.push("right"),
                    b'D' => out.push("left"),
                    _ => {}
                }
                i += 3;
                continue;
            }
            b'+' | b'=' => out.push("stronger"),
            b'-' | b'_' => out.push("weaker"),
            b'q' | b'Q' | 3 | 4 => out.push("quit"),
            _ => {}
        }
        i += 1;
    }
    out
}

/// `frond control`: keys from a terminal (raw mode), or key names one per line from a pipe.
pub(crate) fn control(g: &Global) -> anyhow::Result<()> {
    let mut c = Control::from_global(g)?;
    let send = |c: &mut Control, key: &str| -> anyhow::Result<()> {
        send_key(c, key, None)?;
        frond_binmain::out!("\r\x1b[K")?;
        print_field_state(c)?;
        io::stdout().flush()?;
        Ok(())
    };
    if io::stdin().is_terminal() {
        frond_binmain::outln!("arrows: force direction, + / -: strength, q: quit")?;
        let _raw = RawMode::enter();
        let mut buf = [0u8; 16];
        loop {
            let n = io::stdin().read(&mut buf)?;
            if n == 0 {
                return Ok(());
            }
            for key in keys_from_bytes(&buf[..n]) {
                if key == "quit" {
                    return Ok(());
                }
                send(&mut c, key)?;
            }
        }
    }
    for line in io::stdin().lock().lines() {
        let line = line?;
        let key = line.trim();
        if key.is_empty() {
            continue;
        }
        if key == "q" || key == "quit" {
            break;
        }
        send(&mut c, key)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn terminal_bytes_become_keys() {
        assert_eq!(keys_from_bytes(b"\x1b[A\x1b[D+-q"), ["up", "left", "stronger", "weaker", "quit"]);
        assert_eq!(keys_from_bytes(b"\x1b[C\x1b[B=x"), ["right", "down", "stronger"]);
        assert!(keys_from_bytes(b"\x1b[").is_empty());
    }
}
