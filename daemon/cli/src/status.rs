//! `frond status`: the daemon's state as a readable table or JSON.

use std::fmt::Write as _;

use frond_protocol::StatusReport;

use crate::control::Control;
use crate::global::Global;

/// How long `frond status --from zenoh:...` waits for a bridge to answer.
const STATUS_WAIT: std::time::Duration = std::time::Duration::from_secs(5);

pub(crate) fn run(g: &Global, json: bool, from: Option<&frond_sdk::Source>) -> anyhow::Result<()> {
    match from {
        Some(frond_sdk::Source::Zenoh(addr)) => run_zenoh(addr, json),
        Some(frond_sdk::Source::Socket(dir)) => print(&Control::connect(dir)?.status()?, json),
        None => print(&Control::from_global(g)?.status()?, json),
    }
}

fn print(report: &frond_protocol::StatusReport, json: bool) -> anyhow::Result<()> {
    if json {
        frond_binmain::outln!("{}", serde_json::to_string_pretty(report)?)?;
    } else {
        frond_binmain::out!("{}", render(report))?;
    }
    Ok(())
}

/// `frond status --from zenoh:...`: the status of every source the key matches (one for a
/// concrete key, each under a `== <stage>/<source>` heading for a selector such as
/// `frond/<stage>/*`), each followed by its bridge's Zenoh subscribers as the bridge counts them
/// (issue 43: what each peer got, missed and recovered). JSON: for a concrete key, the report
/// with a `zenoh_peers` list; for a selector, an object from each source to that.
fn run_zenoh(addr: &frond_sdk::ZenohAddr, json: bool) -> anyhow::Result<()> {
    let session = frond_sdk::zenoh::open_addr_session(addr)?;
    // A concrete key is one source's: only a selector can match several.
    let reports = frond_sdk::zenoh::query_statuses_in(&session, addr, STATUS_WAIT)?;
    let short = frond_sdk::zenoh_many::short;
    let mut map = serde_json::Map::new();
    for (i, (key, report)) in reports.iter().enumerate() {
        // A bridge too old to answer, or gone since: its report without a list.
        let peers = frond_sdk::zenoh_replay::query_peers(&session, key, PEERS_WAIT).ok();
        if json {
            let mut value = serde_json::to_value(report)?;
            value["zenoh_peers"] = serde_json::to_value(&peers)?;
            map.insert(short(key).to_owned(), value);
            continue;
        }
        if !addr.is_concrete() {
            if i > 0 {
                frond_binmain::outln!()?;
            }
            frond_binmain::outln!("== {}", frond_protocol::printable(short(key)))?;
        }
        frond_binmain::out!("{}", render(report))?;
        frond_binmain::out!("{}", render_peers(peers.as_deref()))?;
    }
    if json {
        let value = if addr.is_concrete() {
            map.into_iter().next().map(|(_, one)| one).unwrap_or_default()
        } else {
            serde_json::Value::Object(map)
        };
        frond_binmain::outln!("{}", serde_json::to_string_pretty(&value)?)?;
    }
    Ok(())
}

/// How long `frond status --from zenoh:...` waits for a bridge's list of its subscribers.
const PEERS_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// The bridge's subscribers, one line each (names and counts as the bridge reports them;
/// names come from the network, so they are shown printable).
fn render_peers(peers: Option<&[frond_sdk::zenoh_replay::PeerReport]>) -> String {
    use std::fmt::Write as _;
    let Some(peers) = peers else { return "zenoh peers  (the bridge did not say)\n".into() };
    let mut o = format!("zenoh peers  {} reporting\n", peers.len());
    for p in peers {
        let _ = writeln!(
            o,
            "  {:<34} {} frames, {} missing, {} recovered ({} replayed), {} ago",
            frond_protocol::printable(&p.peer),
            p.frames,
            p.missing,
            p.recovered,
            p.replayed,
            human_duration(p.seen_ms_ago as f64 / 1000.0)
        );
    }
    o
}

/// `1h 02m 03s`, `2m 05s`, `4.2s`.
pub(crate) fn human_duration(s: f64) -> String {
    if !s.is_finite() || s < 0.0 {
        return "?".into();
    }
    let whole = s as u64;
    match whole {
        0..60 => format!("{s:.1}s"),
        60..3600 => format!("{}m {:02}s", whole / 60, whole % 60),
        _ => format!("{}h {:02}m {:02}s", whole / 3600, whole / 60 % 60, whole % 60),
    }
}

/// The readable status table. Every string in a report came from outside (a calibration's id,
/// a device's path, a take's name, a stage's own words, a remote bridge's whole report), so each
/// is printed with its control characters escaped ([`frond_protocol::printable`]): no value can
/// end its line and draw a status line of its own, or move the cursor over a real one.
pub(crate) fn render(r: &StatusReport) -> String {
    use frond_protocol::printable as p;
    let mut o = String::new();
    let _ = writeln!(o, "daemon       frondd {}, up {}", p(&r.daemon_version), human_duration(r.uptime_s));
    for problem in &r.problems {
        let _ = writeln!(o, "PROBLEM      {}", p(problem));
    }
    hands(&mut o, r);
    let _ = writeln!(o, "rig          {}", p(&r.rig_name));
    let _ = writeln!(o, "calibration  {}", p(&r.calibration_id));
    let _ = writeln!(o, "filter       {}", p(&r.filter));
    let _ = writeln!(
        o,
        "rate         {} Hz nominal, {:.1} Hz achieved ({} ticks, {} held, {} device wakes, {} publish drops)",
        r.tick_rate_hz, r.achieved_rate_hz, r.ticks, r.held_ticks, r.device_wakes, r.publish_drops
    );
    let l = &r.lateness;
    let _ = writeln!(
        o,
        "lateness     p50 {:.1} us, p99 {:.1} us, p99.9 {:.1} us, max {:.1} us ({} samples)",
        l.p50_us, l.p99_us, l.p999_us, l.max_us, l.samples
    );
    if !r.realtime.is_empty() {
        let _ = writeln!(o, "realtime     {}", p(&r.realtime));
    }
    recording_and_subscribers(&mut o, r);
    if let Some(t) = &r.triggers {
        triggers(&mut o, t);
    }
    if let Some(l) = &r.ltc {
        ltc(&mut o, l);
    }
    stages_elements_and_events(&mut o, r);
    o
}

/// [`render`]'s capture triggers: where frond listens and leads, the last message, the counts.
fn triggers(o: &mut String, t: &frond_protocol::TriggerStatus) {
    use frond_protocol::printable as p;
    let follows = match &t.listen {
        Some(addr) if t.allow.is_empty() => format!("listening on {} (any host)", p(addr)),
        Some(addr) => format!("listening on {} (from {})", p(addr), p(&t.allow.join(", "))),
        None => "not following".to_string(),
    };
    let leads = t.lead.as_ref().map_or("not leading".to_string(), |to| format!("leading to {}", p(to)));
    let _ = writeln!(o, "triggers     {follows}; {leads}");
    if t.paused {
        let _ = writeln!(
            o,
            "  PAUSED     starts are not followed ({} heard while paused); `frond triggers follow` resumes",
            t.paused_starts
        );
    }
    if let Some(last) = &t.last {
        let name = last.name.as_deref().map_or("(no name)".to_string(), |n| format!("\"{}\"", p(n)));
        let packet = last.packet_id.map_or(String::new(), |id| format!(", packet {id}"));
        let _ = writeln!(
            o,
            "  last       {} {name} from {}{packet}, {} ago",
            p(&last.kind),
            p(&last.from),
            human_duration(last.age_s)
        );
    }
    if let Some(name) = &t.scheduled {
        let _ = writeln!(o, "  scheduled  {} (waiting for its delay)", p(name));
    }
    let _ = writeln!(
        o,
        "  counts     {} received, {} accepted ({} started, {} stopped), {} duplicates, {} out of order, \
         {} foreign, {} malformed, {} oversized, {} stops without a take, {} starts refused",
        t.received,
        t.accepted,
        t.started,
        t.stopped,
        t.duplicates,
        t.out_of_order,
        t.foreign,
        t.malformed,
        t.oversized,
        t.stops_without_take,
        t.start_refused
    );
    if t.lead.is_some() {
        let _ = writeln!(o, "  lead       {} sent, {} failed", t.lead_sent, t.lead_failed);
    }
    if let Some(why) = &t.last_refused {
        let _ = writeln!(o, "  refused    {}", p(why));
    }
}

/// [`render`]'s stage timecode: the LTC input, its state, the last label and the counts.
fn ltc(o: &mut String, l: &frond_protocol::LtcStatus) {
    use frond_protocol::printable as p;
    let fps = l.fps.as_deref().map_or(String::new(), |f| format!(" at {} fps", p(f)));
    let _ = writeln!(o, "ltc          {}{fps} from {} ({} Hz)", p(&l.state), p(&l.input), l.sample_rate_hz);
    if let Some(tc) = &l.last_timecode {
        let age = l.last_age_s.map_or(String::new(), |a| format!(", {} ago", human_duration(a)));
        let _ = writeln!(o, "  last       {}{age}", p(tc));
    }
    // Overruns only happen on a capture device: shown when there were any.
    let overruns = if l.overruns > 0 { format!(", {} ALSA overruns", l.overruns) } else { String::new() };
    let _ = writeln!(
        o,
        "  counts     {} frames, {} locks, {} losses, {} jumps{overruns}",
        l.frames, l.locks, l.losses, l.jumps
    );
    if let Some(e) = &l.last_error {
        let _ = writeln!(o, "  error      {}", p(e));
    }
}

/// One hand source's line: kind, path, connection and counts.
fn source_line(s: &frond_protocol::SourceStatus) -> String {
    use frond_protocol::printable as p;
    format!(
        "{} {} ({}; {} reports, {} rejected, {} device sequence gaps)",
        p(&s.kind),
        p(&s.path),
        if s.connected { "connected" } else { "NOT CONNECTED" },
        s.reports,
        s.rejected,
        s.device_seq_gaps
    ) + &s.camera.as_ref().map(camera_text).unwrap_or_default()
}

/// A camera source's frames: `; camera 29.9 fps, 41.2 ms frame to sample (model 13.5 ms), 12 of 900 frames without a hand`,
/// and the picture it keeps for the console (`, picture webcam-1.jpg in the socket directory`).
fn camera_text(c: &frond_protocol::CameraStatus) -> String {
    let restarts = if c.helper_starts > 1 {
        format!(", helper started {} times", c.helper_starts)
    } else {
        String::new()
    };
    // Only a name that is a picture's (it comes from the daemon, and is printed).
    let picture = match c.preview.as_deref().filter(|n| frond_protocol::paths::is_camera_preview_name(n)) {
        Some(name) => format!(", picture {name} in the socket directory"),
        None => String::new(),
    };
    format!(
        "; camera {:.1} fps, {:.1} ms frame to sample (model {:.1} ms), {} of {} frames without a hand{restarts}{picture}",
        c.fps, c.latency_ms, c.model_ms, c.empty_frames, c.frames
    )
}

/// [`render`]'s hand sources: one `source` line, or each hand with its element and counts.
fn hands(o: &mut String, r: &StatusReport) {
    use frond_protocol::printable as p;
    if r.hands.len() > 1 {
        let _ = writeln!(o, "hands        {}", r.hands.len());
        for h in &r.hands {
            let name = p(&h.name);
            let _ = writeln!(o, "  {name}: {}", source_line(&h.source));
            let _ = writeln!(
                o,
                "  {:w$}  -> element {} {} (rig {}, calibration {}); {} frames, {} held, {} stalls, {} lost",
                "",
                h.element,
                p(&h.element_name),
                p(&h.rig_name),
                p(&h.calibration_id),
                h.frames,
                h.held_frames,
                h.stalls,
                h.lost_events,
                w = name.chars().count()
            );
        }
    } else {
        let _ = writeln!(o, "source       {}", source_line(&r.source));
    }
}

/// [`render`]'s recording, recorder error and subscribers.
fn recording_and_subscribers(o: &mut String, r: &StatusReport) {
    use frond_protocol::printable as p;
    match &r.recording {
        Some(rec) => {
            let _ = writeln!(
                o,
                "recording    {} {} -> {} ({} frames, {} dropped)",
                if rec.active { "RECORDING" } else { "stopped" },
                p(&rec.name),
                p(&rec.path),
                rec.frames,
                rec.dropped
            );
        }
        None => {
            let _ = writeln!(o, "recording    no");
        }
    }
    if let Some(e) = &r.recorder_error {
        let _ = writeln!(o, "recorder     ERROR: {}", p(e));
    }
    let _ = writeln!(o, "subscribers  {}", r.subscribers.len());
    if !r.subscribers.is_empty() {
        let _ = writeln!(o, "  {:>6} {:>12} {:>12} {:>10}", "id", "connected", "sent", "dropped");
        for s in &r.subscribers {
            let _ = writeln!(
                o,
                "  {:>6} {:>12} {:>12} {:>10}",
                s.id,
                human_duration(s.connected_s),
                s.sent,
                s.dropped
            );
        }
    }
}

/// [`render`]'s live stages, elements and device events.
fn stages_elements_and_events(o: &mut String, r: &StatusReport) {
    use frond_protocol::printable as p;
    if r.stages.is_empty() {
        let _ = writeln!(o, "stages       none");
    } else {
        let _ = writeln!(o, "stages       {}", r.stages.len());
        for st in &r.stages {
            let _ = writeln!(o, "  {} ({}): {}", p(&st.name), p(&st.kind), p(&st.state));
        }
    }
    if !r.elements.is_empty() {
        let _ = writeln!(o, "elements     {}", element_groups(&r.elements).join("; "));
    }
    if r.device_events.is_empty() {
        let _ = writeln!(o, "device events: none");
    } else {
        let _ = writeln!(o, "device events (oldest first):");
        for e in &r.device_events {
            let _ = writeln!(o, "  {}", p(e));
        }
    }
}

/// Elements in runs of one kind and source: `0 hand grass`, `33-48 field-plant (field, 16)`.
fn element_groups(elements: &[frond_protocol::ElementInfo]) -> Vec<String> {
    use frond_protocol::printable as p;
    let mut out = Vec::new();
    let mut i = 0;
    while i < elements.len() {
        let e = &elements[i];
        let mut j = i + 1;
        while j < elements.len() && elements[j].kind == e.kind && elements[j].source == e.source {
            j += 1;
        }
        if j - i == 1 {
            out.push(format!("{} {} {} ({})", e.id, e.kind.as_str(), p(&e.name), p(&e.source)));
        } else {
            out.push(format!(
                "{}-{} {} ({}, {})",
                e.id,
                elements[j - 1].id,
                e.kind.as_str(),
                p(&e.source),
                j - i
            ));
        }
        i = j;
    }
    out
}

#[cfg(test)]
mod tests {
    use frond_protocol::{LatencySummary, RecordingStatus, SourceStatus, SubscriberStatus};

    use super::*;

    #[test]
    fn a_cameras_line_names_its_rate_latency_and_picture() {
        let mut c = frond_protocol::CameraStatus {
            frames: 900,
            empty_frames: 12,
            fps: 29.94,
            latency_ms: 41.24,
            model_ms: 13.5,
            helper_starts: 2,
            preview: Some("webcam-1.jpg".into()),
        };
        assert_eq!(
            camera_text(&c),
            "; camera 29.9 fps, 41.2 ms frame to sample (model 13.5 ms), 12 of 900 frames without a hand, \
             helper started 2 times, picture webcam-1.jpg in the socket directory"
        );
        // A name that is no picture's is not printed.
        c.preview = Some("../x\x1b[2J".into());
        assert!(!camera_text(&c).contains("picture"));
    }

    fn report() -> StatusReport {
        StatusReport {
            daemon_version: "0.1.0".into(),
            uptime_s: 3725.0,
            source: SourceStatus {
                kind: "fuse-hidraw".into(),
                path: "/tmp/vhid/hidraw0".into(),
                connected: true,
                reports: 1234,
                rejected: 5,
                device_seq_gaps: 1,
                rejected_by_reason: Default::default(),
                peers_dropped: 0,
                camera: None,
            },
            rig_name: "grass".into(),
            calibration_id: "alice".into(),
            filter: "one-euro:min_cutoff=1,beta=0.007,d_cutoff=1".into(),
            tick_rate_hz: 1000,
            achieved_rate_hz: 999.94,
            ticks: 5000,
            held_ticks: 12,
            device_wakes: 4988,
            publish_drops: 0,
            lateness: LatencySummary {
                p50_us: 12.5,
                p99_us: 40.0,
                p999_us: 80.31,
                max_us: 120.0,
                samples: 1000,
            },
            subscribers: vec![SubscriberStatus { id: 7, connected_s: 65.0, sent: 4321, dropped: 3, pid: 0 }],
            recording: Some(RecordingStatus {
                name: "take1".into(),
                path: "/d/take1.take".into(),
                frames: 99,
                dropped: 0,
                active: true,
            }),
            device_events: vec!["connected /tmp/vhid/hidraw0".into()],
            realtime: "normal".into(),
            modes: vec![],
            stages: vec![],
            elements: vec![],
            hands: vec![],
            problems: vec![],
            recorder_error: None,
            lateness_histogram: Vec::new(),
            triggers: None,
            ltc: None,
        }
    }

    /// Issue 46: the LTC section says the state, rate, input, last label and counts.
    #[test]
    fn the_ltc_section_shows_state_last_timecode_and_counts() {
        let mut r = report();
        assert!(!render(&r).contains("ltc "));
        r.ltc = Some(frond_protocol::LtcStatus {
            input: "/run/frond/ltc.fifo".into(),
            state: "locked".into(),
            fps: Some("25".into()),
            last_timecode: Some("10:00:01:07".into()),
            last_age_s: Some(0.02),
            sample_rate_hz: 48_000,
            frames: 32,
            locks: 1,
            losses: 0,
            jumps: 2,
            last_error: None,
            overruns: 0,
        });
        let t = render(&r);
        for needle in [
            "ltc          locked at 25 fps from /run/frond/ltc.fifo (48000 Hz)\n",
            "  last       10:00:01:07, 0.0s ago\n",
            "  counts     32 frames, 1 locks, 0 losses, 2 jumps\n",
        ] {
            assert!(t.contains(needle), "missing {needle:?} in:\n{t}");
        }
        // A capture device that fell behind says how often.
        r.ltc.as_mut().unwrap().overruns = 3;
        assert!(render(&r).contains("  counts     32 frames, 1 locks, 0 losses, 2 jumps, 3 ALSA overruns\n"));
    }

    /// Issue 46: the trigger section says where frond listens and leads, the last message and
    /// the counts, each value escaped as every other.
    #[test]
    fn the_trigger_section_shows_listening_leading_last_and_counts() {
        let mut r = report();
        assert!(!render(&r).contains("triggers"));
        r.triggers = Some(frond_protocol::TriggerStatus {
            listen: Some("0.0.0.0:30".into()),
            allow: vec!["10.0.0.5".into()],
            lead: Some("255.255.255.255:30".into()),
            last: Some(frond_protocol::TriggerLast {
                kind: "CaptureStart".into(),
                name: Some("dance\u{1b}[2J".into()),
                from: "10.0.0.5".into(),
                packet_id: Some(33360),
                age_s: 2.0,
            }),
            last_refused: Some("10.0.0.9: not in triggers.allow".into()),
            received: 7,
            accepted: 2,
            started: 1,
            stopped: 1,
            duplicates: 1,
            foreign: 2,
            malformed: 1,
            oversized: 1,
            lead_sent: 4,
            ..Default::default()
        });
        let t = render(&r);
        for needle in [
            "triggers     listening on 0.0.0.0:30 (from 10.0.0.5); leading to 255.255.255.255:30\n",
            "  last       CaptureStart \"dance\\u{1b}[2J\" from 10.0.0.5, packet 33360, 2.0s ago\n",
            "  counts     7 received, 2 accepted (1 started, 1 stopped), 1 duplicates, 0 out of order, 2 foreign, \
             1 malformed, 1 oversized, 0 stops without a take, 0 starts refused\n",
            "  lead       4 sent, 0 failed\n",
            "  refused    10.0.0.9: not in triggers.allow\n",
        ] {
            assert!(t.contains(needle), "missing {needle:?} in:\n{t}");
        }
    }

    #[test]
    fn the_table_shows_every_field() {
        let t = render(&report());
        for needle in [
            "frondd 0.1.0, up 1h 02m 05s",
            "fuse-hidraw /tmp/vhid/hidraw0 (connected; 1234 reports, 5 rejected, 1 device sequence gaps)",
            "rig          grass",
            "calibration  alice",
            "filter       one-euro:min_cutoff=1,beta=0.007,d_cutoff=1",
            "1000 Hz nominal, 999.9 Hz achieved (5000 ticks, 12 held, 4988 device wakes, 0 publish drops)",
            "p50 12.5 us, p99 40.0 us, p99.9 80.3 us, max 120.0 us (1000 samples)",
            "RECORDING take1 -> /d/take1.take (99 frames, 0 dropped)",
            "subscribers  1",
            "connected /tmp/vhid/hidraw0",
        ] {
            assert!(t.contains(needle), "missing {needle:?} in\n{t}");
        }
        let sub_line = t.lines().find(|l| l.trim_start().starts_with("7 ")).unwrap();
        let cols: Vec<&str> = sub_line.split_whitespace().collect();
        assert_eq!(cols, ["7", "1m", "05s", "4321", "3"]);
        assert!(!t.contains("recorder"), "{t}");
        let mut r = report();
        r.recorder_error = Some("writing take /d/take1.take failed: writing: No space left".into());
        let t = render(&r);
        assert!(t.contains("recorder     ERROR: writing take /d/take1.take failed"), "{t}");
    }

    #[test]
    fn stages_and_element_runs_are_listed() {
        use frond_protocol::{ElementId, ElementInfo, ElementKind, StageStatus};
        let mut r = report();
        assert!(render(&r).contains("stages       none"));
        let e = |id: u16, kind: ElementKind, name: &str, source: &str| ElementInfo {
            id: ElementId::new(id),
            name: name.into(),
            kind,
            source: source.into(),
            rig: "grass".into(),
        };
        r.elements = vec![
            e(0, ElementKind::Hand, "grass", "hand"),
            e(33, ElementKind::FieldPlant, "plant0", "field"),
            e(34, ElementKind::FieldPlant, "plant1", "field"),
            e(35, ElementKind::FieldPlant, "plant2", "field"),
        ];
        r.stages = vec![StageStatus {
            name: "field".into(),
            kind: "field".into(),
            state: "field of g: 3 plants".into(),
            elements: [33, 34, 35].map(ElementId::new).to_vec(),
            dropped_work: 0,
        }];
        let t = render(&r);
        assert!(t.contains("stages       1\n  field (field): field of g: 3 plants\n"), "{t}");
        assert!(t.contains("elements     0 hand grass (hand); 33-35 field-plant (field, 3)\n"), "{t}");
    }

    #[test]
    fn several_hands_get_a_line_each() {
        use frond_protocol::{ElementId, HandStatus};
        let mut r = report();
        let hand = |name: &str, connected: bool, element: u16, element_name: &str| HandStatus {
            name: name.into(),
            source: SourceStatus {
                kind: "fuse-hidraw".into(),
                path: format!("/tmp/{name}"),
                connected,
                reports: 10,
                rejected: 0,
                device_seq_gaps: 0,
                rejected_by_reason: Default::default(),
                peers_dropped: 0,
                camera: None,
            },
            element: ElementId::new(element),
            element_name: element_name.into(),
            rig_name: "flower".into(),
            calibration_id: "none".into(),
            frames: 10,
            held_frames: 2,
            stalls: 0,
            lost_events: u64::from(!connected),
            discontinuities: 0,
            stale_skipped: 0,
            events: vec![],
        };
        r.hands = vec![hand("left", true, 0, "flower"), hand("right", false, 1, "leaf")];
        let t = render(&r);
        assert!(!t.contains("\nsource "), "one source line is replaced by the hands:\n{t}");
        assert!(t.contains("hands        2\n"), "{t}");
        assert!(t.contains("  left: fuse-hidraw /tmp/left (connected; 10 reports"), "{t}");
        assert!(t.contains("  right: fuse-hidraw /tmp/right (NOT CONNECTED; 10 reports"), "{t}");
        assert!(
            t.contains(
                "-> element 1 leaf (rig flower, calibration none); 10 frames, 2 held, 0 stalls, 1 lost"
            ),
            "{t}"
        );
    }

    #[test]
    fn no_value_from_outside_can_draw_a_line_of_its_own() {
        use frond_protocol::{ElementId, ElementInfo, ElementKind, HandStatus, StageStatus};
        // Each string a hostile calibration, device, take, stage or remote bridge could set,
        // carrying a line break and a fake line (or an escape sequence that moves the cursor).
        let fake = "x\nPROBLEM      none\r\u{1b}[2K\u{1b}[1A";
        let mut r = report();
        r.daemon_version = fake.into();
        r.problems = vec![fake.into()];
        r.source.kind = fake.into();
        r.source.path = fake.into();
        r.rig_name = fake.into();
        r.calibration_id = fake.into();
        r.filter = fake.into();
        r.realtime = fake.into();
        r.recorder_error = Some(fake.into());
        r.device_events = vec![fake.into()];
        if let Some(rec) = &mut r.recording {
            rec.name = fake.into();
            rec.path = fake.into();
        }
        r.stages = vec![StageStatus {
            name: fake.into(),
            kind: fake.into(),
            state: fake.into(),
            elements: vec![],
            dropped_work: 0,
        }];
        r.elements = vec![
            ElementInfo {
                id: ElementId::GLOBAL,
                name: fake.into(),
                kind: ElementKind::Hand,
                source: fake.into(),
                rig: fake.into(),
            },
            ElementInfo {
                id: ElementId::new(33),
                name: fake.into(),
                kind: ElementKind::FieldPlant,
                source: fake.into(),
                rig: fake.into(),
            },
            ElementInfo {
                id: ElementId::new(34),
                name: fake.into(),
                kind: ElementKind::FieldPlant,
                source: fake.into(),
                rig: fake.into(),
            },
        ];
        let t = render(&r);
        let clean = render(&report());
        // The same table with every value on its own line: lines as many as the clean table's
        // plus one per added list entry (a problem, a stage heading and line, an elements line),
        // and no control character but the line ends.
        assert_eq!(t.lines().count(), clean.lines().count() + 4, "{t}");
        assert!(!t.chars().any(|c| c.is_control() && c != '\n'), "{t:?}");
        assert_eq!(t.lines().filter(|l| l.starts_with("PROBLEM")).count(), 1, "{t}");
        assert!(t.contains("calibration  x\\nPROBLEM      none\\r\\u{1b}[2K\\u{1b}[1A\n"), "{t}");
        // Several hands: each hand's strings too.
        let mut h = HandStatus {
            name: fake.into(),
            source: r.source.clone(),
            element: ElementId::FIRST_LAYER,
            element_name: fake.into(),
            rig_name: fake.into(),
            calibration_id: fake.into(),
            frames: 1,
            held_frames: 0,
            stalls: 0,
            lost_events: 0,
            discontinuities: 0,
            stale_skipped: 0,
            events: vec![],
        };
        r.hands = vec![h.clone()];
        h.name = "b".into();
        r.hands.push(h);
        let t2 = render(&r);
        assert_eq!(t2.lines().count(), t.lines().count() + 4, "hands: a count and two lines each\n{t2}");
        assert!(!t2.chars().any(|c| c.is_control() && c != '\n'), "{t2:?}");
    }

    #[test]
    fn durations_read_naturally() {
        assert_eq!(human_duration(4.25), "4.2s");
        assert_eq!(human_duration(125.0), "2m 05s");
        assert_eq!(human_duration(3600.0 * 2.0 + 61.0), "2h 01m 01s");
        assert_eq!(human_duration(f64::NAN), "?");
    }
}
