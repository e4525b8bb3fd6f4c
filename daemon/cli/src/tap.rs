//! `frond tap`: live poses from the daemon, one line each.
//!
//! Held frames (ticks without a new device report, flag `held`) repeat the previous pose; they
//! are skipped by default so each line is one new device sample, exactly what `frond map` prints
//! for the same input. `--include-held` prints every tick. Lines are flushed one by one; a closed
//! stdout (`| head`) ends quietly.

use std::fmt::Write as _;
use std::io::Write;

use anyhow::Context;
use frond_formats::jsonl::write_pose_line;
use frond_motion::PoseFrame;
use frond_protocol::{ElementId, Pose, PoseFlags, paths};
use std::time::Duration;

use frond_sdk::{Event, SdkError, Subscriber};

use crate::global::Global;

/// `frond tap` on one source: this host's daemon, or one bridge (`--from` a concrete
/// address; a selector over several is followed by the `tap_stage` module).
pub(crate) fn run(
    g: &Global,
    jsonl: bool,
    count: Option<u64>,
    include_held: bool,
    element: Option<&str>,
    from: Option<&frond_sdk::Source>,
) -> anyhow::Result<()> {
    let dir = paths::socket_dir(g.socket_dir.clone());
    let source = from.cloned().unwrap_or_else(|| frond_sdk::Source::Socket(dir.clone()));
    let mut sub = subscribe(&dir, &source)?;
    let mut names = sub.hello().joint_names.clone();
    // `--element`: an id, or a name looked up in the element table (again when it changes).
    let pick = |table: &frond_protocol::ElementTable| {
        pick_element(element, table).or_else(|e| crate::error::usage(e.to_string()))
    };
    let mut table = sub.elements().clone();
    let mut only = pick(&table)?;
    if let Some(note) = unannounced(only, &table) {
        frond_binmain::errln!("frond tap: {note}");
    }
    let mut printer = Printer::new(jsonl, count);
    if count == Some(0) {
        return Ok(());
    }
    let mut silence = Silence::new(std::time::Instant::now());
    loop {
        let event = match sub.next_event() {
            Err(SdkError::Timeout { .. }) => None,
            other => Some(other.context("reading the pose stream")?),
        };
        if let Some(note) = silence.check(std::time::Instant::now(), &source, element) {
            frond_binmain::errln!("frond tap: {note}");
        }
        let Some(event) = event else { continue };
        match event {
            Event::Pose(pose) => {
                if pose.flags.contains(PoseFlags::HELD) && !include_held {
                    silence.held += 1;
                    continue;
                }
                if only.is_some_and(|id| id != pose.element) {
                    silence.other += 1;
                    continue;
                }
                silence.printed(std::time::Instant::now());
                if printer.print(&pose, &names, &table, None)? {
                    return Ok(());
                }
            }
            Event::Gap { expected, got } => {
                frond_binmain::errln!(
                    "frond tap: gap: {} frames missing (seq {expected}..{})",
                    got - expected,
                    got - 1
                );
            }
            Event::RigChanged(h) => {
                frond_binmain::errln!("frond tap: rig changed to {}", frond_protocol::printable(&h.rig_name));
                names = h.joint_names;
            }
            Event::Reconnected(h) => {
                frond_binmain::errln!(
                    "frond tap: reconnected (daemon {}, rig {})",
                    frond_protocol::printable(&h.daemon_version),
                    frond_protocol::printable(&h.rig_name)
                );
                names = h.joint_names;
            }
            Event::Elements(new) => {
                say_elements(&new);
                table = new;
                if element.is_some_and(|e| e.parse::<ElementId>().is_err()) {
                    only = pick(&table)?;
                }
                if let Some(note) = unannounced(only, &table) {
                    frond_binmain::errln!("frond tap: {note}");
                }
            }
            Event::Disconnected => {
                frond_binmain::errln!("frond tap: the daemon closed the stream; reconnecting")
            }
        }
    }
}

/// Subscribes to `source`'s poses, reading with a timeout so that a silent stream is noticed;
/// a daemon not running at `dir` is said with how to start it.
fn subscribe(dir: &std::path::Path, source: &frond_sdk::Source) -> anyhow::Result<Subscriber> {
    Subscriber::options().read_timeout(Some(SILENCE_POLL)).subscribe(source).map_err(|e| match e {
        SdkError::NotRunning { source, .. } => anyhow::anyhow!(frond_sdk::control::not_running_message(
            &dir.join(frond_protocol::POSES_SOCKET),
            &source
        )),
        other => other.into(),
    })
}

/// Says a new element table on stderr: `id kind name` each.
fn say_elements(table: &frond_protocol::ElementTable) {
    let list: Vec<String> = table
        .elements
        .iter()
        .map(|e| format!("{} {} {}", e.id, e.kind.as_str(), frond_protocol::printable(&e.name)))
        .collect();
    frond_binmain::errln!("frond tap: elements now: {}", list.join(", "));
}

/// How often `frond tap` looks up from a silent stream.
const SILENCE_POLL: Duration = Duration::from_millis(250);
/// How long without a pose to print before `frond tap` says why it prints nothing.
const SILENCE_NOTICE: Duration = Duration::from_secs(2);

/// Tracks how long `frond tap` has printed nothing, and what it skipped meanwhile, to say once
/// per silence what is wrong instead of waiting without a word.
struct Silence {
    since: std::time::Instant,
    said: bool,
    /// Held frames skipped (the daemon repeating the last pose: no new report from the hand).
    held: u64,
    /// Frames of other elements than `--element` skipped.
    other: u64,
}

impl Silence {
    fn new(now: std::time::Instant) -> Self {
        Silence { since: now, said: false, held: 0, other: 0 }
    }

    fn printed(&mut self, now: std::time::Instant) {
        *self = Silence::new(now);
    }

    /// The note to print when nothing has been printed for [`SILENCE_NOTICE`] (once a silence).
    fn check(
        &mut self,
        now: std::time::Instant,
        source: &frond_sdk::Source,
        element: Option<&str>,
    ) -> Option<String> {
        let quiet = now.duration_since(self.since);
        if self.said || quiet < SILENCE_NOTICE {
            return None;
        }
        self.said = true;
        let from = match source {
            frond_sdk::Source::Socket(dir) => format!("{}", dir.join(frond_protocol::POSES_SOCKET).display()),
            frond_sdk::Source::Zenoh(addr) => format!("zenoh:{addr}"),
        };
        let secs = quiet.as_secs_f64();
        Some(if self.other > 0 {
            format!(
                "nothing to print for {secs:.0} s from {from}: {} frames of other elements, none of --element {};                  `frond tap` without --element shows what is published",
                self.other,
                frond_protocol::printable(element.unwrap_or("?"))
            )
        } else if self.held > 0 {
            format!(
                "nothing to print for {secs:.0} s from {from}: the daemon only repeats the last pose ({} held                  frames), its hand source sends no reports; check the device or glove (`frond status`,                  `frond doctor`), or pass --include-held to print the held frames",
                self.held
            )
        } else {
            format!(
                "no frames for {secs:.0} s from {from}: the source is silent; check that it runs and publishes                  (`frond status`, `frond doctor`; a Zenoh source: its bridge and router)"
            )
        })
    }
}

/// An `--element` name that the element table does not hold ([`pick_element`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--element {want:?}: no such element (announced: {})", announced.join(", "))]
pub(crate) struct NoSuchElement {
    /// The name asked for.
    pub want: String,
    /// The names the table announces.
    pub announced: Vec<String>,
}

/// The element id `--element` (`want`: an id, or a name in `table`) stands for; `None` without
/// `--element`. `Err` says the name is not in the table and names those that are.
pub(crate) fn pick_element(
    want: Option<&str>,
    table: &frond_protocol::ElementTable,
) -> Result<Option<ElementId>, NoSuchElement> {
    let Some(want) = want else { return Ok(None) };
    if let Ok(id) = want.parse::<ElementId>() {
        return Ok(Some(id));
    }
    table.elements.iter().find(|e| e.name == want).map(|e| Some(e.id)).ok_or_else(|| NoSuchElement {
        want: want.to_string(),
        announced: table.elements.iter().map(|e| e.name.clone()).collect(),
    })
}

/// A note for an `--element` id that the table does not announce (yet): tap waits for it, and
/// says so rather than printing nothing without a word.
pub(crate) fn unannounced(only: Option<ElementId>, table: &frond_protocol::ElementTable) -> Option<String> {
    let id = only?;
    if table.get(id).is_some() {
        return None;
    }
    let known: Vec<String> = table.elements.iter().map(|e| format!("{} {}", e.id, e.name)).collect();
    Some(format!(
        "element {id} is not announced (announced: {}); waiting until it is",
        if known.is_empty() { "none".to_string() } else { known.join(", ") }
    ))
}

/// Prints `frond tap`'s lines, one flushed write each, and counts them against `--count`.
pub(crate) struct Printer {
    out: frond_binmain::StdoutWriter,
    line: String,
    jsonl: bool,
    printed: u64,
    count: Option<u64>,
}

impl Printer {
    pub(crate) fn new(jsonl: bool, count: Option<u64>) -> Printer {
        Printer {
            out: frond_binmain::StdoutWriter::lock(),
            line: String::with_capacity(256),
            jsonl,
            printed: 0,
            count,
        }
    }

    /// Prints `pose`'s line: JSON Lines, or readable with `[element]` for any element but the
    /// global one and the joints' `names`. `source` tags it: `"source"` first in JSON Lines, a
    /// `source: ` prefix otherwise. True once `--count` lines are printed.
    pub(crate) fn print(
        &mut self,
        pose: &Pose,
        names: &[String],
        table: &frond_protocol::ElementTable,
        source: Option<&str>,
    ) -> std::io::Result<bool> {
        let line = &mut self.line;
        line.clear();
        if self.jsonl {
            pose_jsonl(pose, line);
            if let Some(source) = source {
                let tag = format!("{{\"source\":{},", serde_json::Value::String(source.to_owned()));
                line.replace_range(0..1, &tag);
            }
        } else {
            if let Some(source) = source {
                let _ = write!(line, "{source}: ");
            }
            if !pose.element.is_global() {
                let name = table.get(pose.element).map_or("?", |e| e.name.as_str());
                let _ = write!(line, "[{}] ", frond_protocol::printable(name));
            }
            pose_human(pose, names, line);
        }
        line.push('\n');
        self.out.write_all(line.as_bytes())?;
        self.out.flush()?;
        self.printed += 1;
        Ok(self.count.is_some_and(|n| self.printed >= n))
    }
}

/// The pose as a `PoseFrame` line: `t` is the device time of the hand sample behind it.
pub(crate) fn pose_frame(pose: &Pose) -> PoseFrame {
    PoseFrame { t: pose.hand.t, joints_deg: pose.joints_deg }
}

/// `{"seq":..,"t":..,"joints":[...]}` exactly as `frond map` formats numbers, plus
/// `"element":N` for any element but the global one (0) and `"flags":[..]` when any flag is
/// set. No newline.
pub(crate) fn pose_jsonl(pose: &Pose, out: &mut String) {
    let start = out.len();
    write_pose_line(&pose_frame(pose), Some(pose.seq), out);
    if !pose.element.is_global() && out[start..].ends_with('}') {
        out.pop();
        let _ = write!(out, ",\"element\":{}}}", pose.element);
    }
    if pose.flags.0 != 0 && out[start..].ends_with('}') {
        out.pop();
        out.push_str(",\"flags\":[");
        for (i, name) in pose.flags.names().enumerate() {
            if i > 0 {
                out.push(',');
            }
            let _ = write!(out, "\"{name}\"");
        }
        if pose.flags.names().next().is_none() {
            // Bits this build has no name for.
            let _ = write!(out, "\"0x{:x}\"", pose.flags.0);
        }
        out.push_str("]}");
    }
}

/// A compact readable line: `#seq t=.. root [p y r] ... flags`.
pub(crate) fn pose_human(pose: &Pose, names: &[String], out: &mut String) {
    let _ = write!(out, "#{:<8} t={:>10.4}", pose.seq, pose.hand.t);
    for (i, j) in pose.joints_deg.iter().enumerate() {
        let name = names.get(i).map(String::as_str).unwrap_or("?");
        let _ = write!(out, "  {name} [{:7.2} {:7.2} {:7.2}]", j[0], j[1], j[2]);
    }
    for name in pose.flags.names() {
        let _ = write!(out, " {name}");
    }
}

#[cfg(test)]
mod tests {
    use frond_protocol::HandWire;

    use super::*;

    #[test]
    fn a_silent_stream_is_said_once_after_two_seconds() {
        let t0 = std::time::Instant::now();
        let src = frond_sdk::Source::Socket("/run/frond".into());
        let mut s = Silence::new(t0);
        s.held = 40;
        assert_eq!(s.check(t0 + Duration::from_millis(1900), &src, None), None);
        let note = s.check(t0 + Duration::from_millis(2100), &src, None).unwrap();
        assert!(note.contains("/run/frond/poses.sock") && note.contains("40 held"), "{note}");
        assert!(note.contains("--include-held"), "{note}");
        assert_eq!(s.check(t0 + Duration::from_secs(9), &src, None), None, "said once");
        // A pose printed: the next silence is said again, here one without any frame.
        s.printed(t0 + Duration::from_secs(10));
        let note = s.check(t0 + Duration::from_secs(13), &src, None).unwrap();
        assert!(note.contains("no frames for 3 s") && note.contains("frond status"), "{note}");
        let mut s = Silence::new(t0);
        s.other = 5;
        let note = s.check(t0 + Duration::from_secs(3), &src, Some("leaf")).unwrap();
        assert!(note.contains("--element leaf"), "{note}");
    }

    fn pose(flags: PoseFlags) -> Pose {
        Pose {
            seq: 42,
            device_time_us: 1_500_000,
            host_monotonic_ns: 9,
            flags,
            element: ElementId::GLOBAL,
            joints_deg: [[1.5, -2.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -3.25]],
            hand: HandWire { t: 1.5, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3] },
        }
    }

    #[test]
    fn jsonl_names_any_element_but_the_global_one() {
        let mut p = pose(PoseFlags::default());
        p.element = ElementId::new(41);
        let mut s = String::new();
        pose_jsonl(&p, &mut s);
        assert!(s.ends_with(",\"element\":41}"), "{s}");
        p.flags = PoseFlags::HELD;
        s.clear();
        pose_jsonl(&p, &mut s);
        assert!(s.ends_with(",\"element\":41,\"flags\":[\"held\"]}"), "{s}");
    }

    #[test]
    fn jsonl_without_flags_is_the_pose_line() {
        let mut s = String::new();
        pose_jsonl(&pose(PoseFlags::default()), &mut s);
        assert_eq!(
            s,
            r#"{"seq":42,"t":1.5,"joints":[[1.5,-2.0,0.0],[0.1,0.0,0.0],[0.0,0.0,0.0],[0.0,0.0,-3.25]]}"#
        );
    }

    #[test]
    fn elements_are_picked_by_id_or_by_name() {
        let table = frond_protocol::ElementTable::default();
        assert_eq!(pick_element(None, &table), Ok(None));
        assert_eq!(pick_element(Some("3"), &table), Ok(Some(ElementId::new(3))));
        assert!(
            pick_element(Some("leaf"), &table).unwrap_err().to_string().contains("\"leaf\": no such element")
        );
        // An id not in the table is waited for, with a word.
        assert_eq!(unannounced(None, &table), None);
        assert_eq!(
            unannounced(Some(ElementId::new(99)), &table).unwrap(),
            "element 99 is not announced (announced: none); waiting until it is"
        );
    }

    #[test]
    fn a_tagged_jsonl_line_is_the_pose_line_with_its_source_first() {
        let mut printer = Printer::new(true, Some(1));
        printer.print(&pose(PoseFlags::default()), &[], &Default::default(), Some("stage1/glove-a")).unwrap();
        let mut plain = String::new();
        pose_jsonl(&pose(PoseFlags::default()), &mut plain);
        assert_eq!(printer.line.trim_end(), format!("{{\"source\":\"stage1/glove-a\",{}", &plain[1..]));
        let v: serde_json::Value = serde_json::from_str(&printer.line).unwrap();
        assert_eq!(v["source"], "stage1/glove-a");
    }

    #[test]
    fn jsonl_names_the_flags() {
        let mut s = String::new();
        pose_jsonl(&pose(PoseFlags::HELD | PoseFlags::FILTERED), &mut s);
        let v: serde_json::Value = serde_json::from_str(&s).unwrap();
        assert_eq!(v["flags"], serde_json::json!(["held", "filtered"]));
        assert_eq!(v["seq"], 42);
        // The line still parses as a pose line with the same frame.
        let (seq, frame) = frond_formats::jsonl::parse_pose_line_with_seq(&s).unwrap();
        assert_eq!(seq, Some(42));
        assert_eq!(frame, pose_frame(&pose(PoseFlags::default())));
    }

    #[test]
    fn unknown_flag_bits_are_shown_in_hex() {
        let mut s = String::new();
        pose_jsonl(&pose(PoseFlags(1 << 20)), &mut s);
        assert!(s.ends_with(r#","flags":["0x100000"]}"#), "{s}");
    }

    #[test]
    fn human_line_uses_joint_names() {
        let mut s = String::new();
        let names: Vec<String> = ["base", "mid", "upper", "tip"].map(String::from).to_vec();
        pose_human(&pose(PoseFlags::HELD), &names, &mut s);
        assert!(s.starts_with("#42"), "{s}");
        assert!(s.contains("base [   1.50   -2.00    0.00]"), "{s}");
        assert!(s.contains("tip [   0.00    0.00   -3.25]"), "{s}");
        assert!(s.ends_with(" held"), "{s}");
    }
}
