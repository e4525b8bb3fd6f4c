//! What is wrong with a stage, in words, with the fix: read from the daemon's
//! [`StatusReport`], so `frond doctor` and the console say the same thing.

use frond_protocol::{LtcStatus, SourceKind, SourceStatus, StatusReport, TriggerStatus};

/// Below this share of the nominal tick rate the loop is reported as slow.
pub const SLOW_RATE_SHARE: f64 = 0.95;

/// One problem and how to fix it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// What is wrong.
    pub what: String,
    /// What to do about it.
    pub fix: String,
}

/// How to bring back a hand source of `kind` (its name in a status reply) that is not
/// connected; a name this SDK does not know gets the general advice.
pub fn source_fix(kind: &str) -> &'static str {
    SourceKind::from_name(kind).map_or(CHECK_THE_SOURCE, source_kind_fix)
}

/// The general advice, for a source with no advice of its own.
const CHECK_THE_SOURCE: &str =
    "check the hand source in frondd.toml or on frondd's command line (`frond doctor`)";

/// How to bring back a hand source of `kind` that is not connected.
pub fn source_kind_fix(kind: SourceKind) -> &'static str {
    match kind {
        SourceKind::Hidraw => {
            "plug the glove in (USB or Bluetooth); the daemon reopens it by itself. If it stays \
             away, `frond doctor` checks the hidraw node, its permissions and the udev rule"
        }
        SourceKind::FuseHidraw => {
            "the virtual glove (frond-vhid) is gone: start it again, or run the daemon on \
             `--source in-process`"
        }
        SourceKind::Osc => {
            "no hand packets arrive: start the tracker bridge that sends /frond/hand (see \
             `frond-vhid --osc` for a reference sender) and check its address and port"
        }
        SourceKind::Leap => {
            "the Leap / Ultraleap tracking service does not answer: start it (its WebSocket on \
             port 6437); the daemon reconnects by itself"
        }
        SourceKind::Webcam => {
            "no hand from the camera: hold a hand up, palm to the camera, in the light; if none \
             is ever found, check that frond-hands is installed (daemon/device/webcam/install.sh) \
             and that the camera is there (`v4l2-ctl --list-devices`)"
        }
        SourceKind::Replay => "the replay ended or its file cannot be read: give another --replay file",
        SourceKind::InProcess => CHECK_THE_SOURCE,
    }
}

fn source_problem(name: &str, s: &SourceStatus) -> Option<Problem> {
    (!s.connected).then(|| Problem {
        what: format!("hand source {name} ({} {}) is not connected", s.kind, s.path),
        fix: source_fix(&s.kind).to_string(),
    })
}

/// Everything in `report` that needs the operator, most urgent first.
pub fn problems(report: &StatusReport) -> Vec<Problem> {
    let mut out = Vec::new();
    if report.hands.is_empty() {
        out.extend(source_problem("hand", &report.source));
    } else {
        out.extend(report.hands.iter().filter_map(|h| source_problem(&h.name, &h.source)));
    }
    if let Some(e) = &report.recorder_error {
        out.push(Problem {
            what: format!("the recording cannot be written: {e}"),
            fix: "free space or fix the takes directory, then `frond record stop`; every complete frame so far \
                  is readable"
                .into(),
        });
    }
    for p in &report.problems {
        out.push(Problem { what: p.clone(), fix: "see the daemon's log (journalctl -u frondd)".into() });
    }
    let nominal = f64::from(report.tick_rate_hz);
    if report.uptime_s > 2.0 && nominal > 0.0 && report.achieved_rate_hz < SLOW_RATE_SHARE * nominal {
        out.push(Problem {
            what: format!(
                "the loop runs at {:.0} Hz of its {} Hz",
                report.achieved_rate_hz, report.tick_rate_hz
            ),
            fix: "the machine is overloaded or the loop has no realtime priority: set realtime.priority in \
                  frondd.toml (`frond doctor` checks the limits)"
                .into(),
        });
    }
    if let Some(t) = &report.triggers {
        out.extend(trigger_problems(t));
    }
    if let Some(l) = &report.ltc {
        out.extend(ltc_problem(l));
    }
    for s in report.subscribers.iter().filter(|s| s.dropped > 0) {
        out.push(Problem {
            what: format!("subscriber {} lost {} frames (it reads too slowly)", s.id, s.dropped),
            fix: "only that subscriber loses frames; give it more CPU or have it read faster".into(),
        });
    }
    out
}

/// What the capture-trigger listener saw that the operator should know: packets from hosts
/// outside its allow-list, packets that are not trigger messages, takes not followed while
/// paused, leader messages not sent.
fn trigger_problems(t: &TriggerStatus) -> Vec<Problem> {
    let mut out = Vec::new();
    let at = t.listen.as_deref().unwrap_or("?");
    let last = t.last_refused.as_deref().map_or(String::new(), |w| format!(" (last: {w})"));
    if t.foreign > 0 {
        out.push(Problem {
            what: format!(
                "the trigger listener on {at} ignored {} packets from hosts outside triggers.allow{last}",
                t.foreign
            ),
            fix: "if that host is the stage master, add its address to triggers.allow in frondd.toml \
                  (or --trigger-allow); otherwise stop it sending to this port"
                .into(),
        });
    }
    let refused = t.malformed + t.oversized;
    if refused > 0 {
        out.push(Problem {
            what: format!(
                "the trigger listener on {at} refused {refused} malformed or oversized packets \
                 ({} malformed, {} oversized){last}",
                t.malformed, t.oversized
            ),
            fix: "something sends to the trigger port in another format: point only the stage master's \
                  CaptureStart/CaptureStop at it (docs/mocap-stage.md), or move triggers.listen to another port"
                .into(),
        });
    }
    if t.paused && t.paused_starts > 0 {
        out.push(Problem {
            what: format!(
                "capture triggers are paused: {} takes the stage started on {at} were not recorded",
                t.paused_starts
            ),
            fix: "run `frond triggers follow` (or turn following on in the console) before the next take"
                .into(),
        });
    }
    if t.lead_failed > 0 {
        out.push(Problem {
            what: format!(
                "{} capture triggers could not be sent to {}",
                t.lead_failed,
                t.lead.as_deref().unwrap_or("?")
            ),
            fix: "check triggers.lead (a broadcast address of this host's network, or the master's \
                  address) and the route to it"
                .into(),
        });
    }
    out
}

/// An LTC input that is configured but not locked: takes get the host's time of day, not
/// the stage's timecode.
fn ltc_problem(l: &LtcStatus) -> Option<Problem> {
    if l.state == "locked" {
        return None;
    }
    let why = match l.state.as_str() {
        "ended" => "its file was read to the end".to_string(),
        "lost" => "it lost the signal".to_string(),
        _ => "no timecode found in it yet".to_string(),
    };
    let error = l.last_error.as_deref().map_or(String::new(), |e| format!("; last error: {e}"));
    Some(Problem {
        what: format!(
            "the stage timecode (LTC from {}) is not locked: {why}{error}; takes carry the host's time of day",
            l.input
        ),
        fix: "check the LTC cable and level into the audio interface and that the capture feeds the input \
              (ltc.input, ltc.sample_rate_hz, ltc.fps in frondd.toml; docs/mocap-stage.md)"
            .into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_ltc_input_that_is_not_locked_is_a_problem() {
        let locked =
            LtcStatus { input: "/run/frond/ltc.fifo".into(), state: "locked".into(), ..Default::default() };
        assert_eq!(ltc_problem(&locked), None);
        let searching = LtcStatus { state: "searching".into(), ..locked.clone() };
        let p = ltc_problem(&searching).unwrap();
        assert_eq!(
            p.what,
            "the stage timecode (LTC from /run/frond/ltc.fifo) is not locked: no timecode found in it yet; \
             takes carry the host's time of day"
        );
        let lost = LtcStatus { state: "lost".into(), last_error: Some("gone".into()), ..locked };
        assert!(ltc_problem(&lost).unwrap().what.contains("it lost the signal; last error: gone"));
    }

    #[test]
    fn a_trigger_listener_that_saw_foreign_or_malformed_packets_is_a_problem() {
        let clean = TriggerStatus { listen: Some("0.0.0.0:30".into()), received: 4, ..Default::default() };
        assert_eq!(trigger_problems(&clean), []);
        let seen = TriggerStatus {
            foreign: 2,
            malformed: 1,
            oversized: 1,
            last_refused: Some("10.0.0.9: not in triggers.allow".into()),
            ..clean
        };
        let problems = trigger_problems(&seen);
        assert_eq!(problems.len(), 2, "{problems:?}");
        assert_eq!(
            problems[0].what,
            "the trigger listener on 0.0.0.0:30 ignored 2 packets from hosts outside triggers.allow \
             (last: 10.0.0.9: not in triggers.allow)"
        );
        assert!(
            problems[1].what.contains("refused 2 malformed or oversized packets (1 malformed, 1 oversized)")
        );
        assert!(problems[0].fix.contains("triggers.allow"));
    }

    #[test]
    fn a_pause_is_a_problem_only_once_it_missed_a_take() {
        let paused = TriggerStatus { listen: Some("0.0.0.0:30".into()), paused: true, ..Default::default() };
        assert_eq!(trigger_problems(&paused), [], "paused by choice, nothing missed yet");
        let missed = TriggerStatus { paused_starts: 3, ..paused.clone() };
        let problems = trigger_problems(&missed);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert_eq!(
            problems[0].what,
            "capture triggers are paused: 3 takes the stage started on 0.0.0.0:30 were not recorded"
        );
        assert!(problems[0].fix.contains("frond triggers follow"));
        // Following again, the starts missed earlier are history, not a problem now.
        assert_eq!(trigger_problems(&TriggerStatus { paused: false, ..missed }), []);
    }

    #[test]
    fn every_source_kind_has_its_own_fix() {
        let fixes: Vec<&str> =
            ["hidraw", "fuse-hidraw", "osc", "leap", "replay", "in-process"].map(source_fix).into();
        for (i, a) in fixes.iter().enumerate() {
            for b in &fixes[i + 1..] {
                assert_ne!(a, b);
            }
        }
        assert!(source_fix("hidraw").contains("plug the glove in"));
        assert!(source_fix("fuse-hidraw").contains("frond-vhid"));
    }
}
