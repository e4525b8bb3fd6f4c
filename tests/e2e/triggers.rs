//! Capture triggers of a mocap stage (issue 46): `frondd --triggers` follows a stage master's
//! `CaptureStart` / `CaptureStop`, and `--trigger-lead` sends frond's own.
//!
//! The sender and the receiver here are written from the published format (Vicon's "UDP capture
//! broadcast/trigger" page, quoted in `daemon/triggers/src/lib.rs`): one XML document per
//! datagram, NUL-terminated, root `CaptureStart` or `CaptureStop`, each field an empty element
//! with a `VALUE` attribute. They are built and read by hand with `format!` and string search,
//! not with frond's own encoder or decoder, so the test checks frond against the format.
//! Everything runs on loopback (a second sender address, 127.0.0.2, plays the foreign host).

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use frond_e2e::{Daemon, wait_for};
use frond_protocol::{StatusReport, TriggerStatus};

/// A free UDP port on 127.0.0.1.
fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// A `CaptureStart` as Vicon's page shows it (with the fields it lists), NUL-terminated.
pub(crate) fn capture_start(name: &str, delay_ms: u32, packet_id: u64) -> Vec<u8> {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStart><Name VALUE=\"{name}\"/>\
         <Notes VALUE=\"\"/><Description VALUE=\"\"/><DatabasePath VALUE=\"D:/Stage/Session 1\"/>\
         <Delay VALUE=\"{delay_ms}\"/><PacketID VALUE=\"{packet_id}\"/></CaptureStart>\0"
    )
    .into_bytes()
}

/// A `CaptureStop` with `RESULT="SUCCESS"`, NUL-terminated.
fn capture_stop(name: &str, packet_id: u64) -> Vec<u8> {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStop RESULT=\"SUCCESS\">\
         <Name VALUE=\"{name}\"/><DatabasePath VALUE=\"D:/Stage/Session 1\"/><Delay VALUE=\"0\"/>\
         <PacketID VALUE=\"{packet_id}\"/></CaptureStop>\0"
    )
    .into_bytes()
}

/// A daemon on the in-process glove following triggers on a free loopback port, and the port's
/// address.
fn following(dir: &std::path::Path) -> (Daemon, String) {
    let listen = format!("127.0.0.1:{}", free_port());
    (Daemon::start(dir, &["--source", "in-process", "--triggers", &listen]), listen)
}

/// The daemon's trigger section (panics when it has none).
fn triggers(daemon: &Daemon) -> TriggerStatus {
    daemon.status().triggers.expect("a trigger section in status")
}

/// Waits until `cond` holds of the status, or panics with `what` and the last status.
fn until(daemon: &Daemon, what: &str, cond: impl Fn(&StatusReport) -> bool) -> StatusReport {
    let mut last = None;
    let held = wait_for(Duration::from_secs(5), || {
        let s = daemon.status();
        let ok = cond(&s);
        last = Some(s);
        ok
    });
    let last = last.unwrap();
    assert!(held, "{what}: {:#?}", last.triggers);
    last
}

/// The number after `<field VALUE="` in `xml`, read by hand.
fn value<'a>(xml: &'a str, field: &str) -> Option<&'a str> {
    let open = format!("<{field} VALUE=\"");
    let start = xml.find(&open)? + open.len();
    Some(&xml[start..start + xml[start..].find('"')?])
}

#[test]
fn triggers_start_and_stop_a_take_ignoring_duplicates_foreign_hosts_and_garbage() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let listen = format!("127.0.0.1:{port}");
    let daemon = Daemon::start(
        dir.path(),
        &["--source", "in-process", "--triggers", &listen, "--trigger-allow", "127.0.0.1"],
    );
    let t = triggers(&daemon);
    assert_eq!(
        (t.listen.as_deref(), t.allow.as_slice(), t.lead.as_deref()),
        (Some(&*listen), &["127.0.0.1".to_string()][..], None)
    );
    let master = UdpSocket::bind("127.0.0.1:0").unwrap();
    let foreign = UdpSocket::bind("127.0.0.2:0").expect("a second loopback address");

    // A foreign host's start, garbage and an oversized datagram change nothing but counts.
    foreign.send_to(&capture_start("intruder", 0, 1), &listen).unwrap();
    master.send_to(b"hello, stage\0", &listen).unwrap();
    master.send_to(&vec![b'<'; 20_000], &listen).unwrap();
    let s = until(&daemon, "refusals counted", |s| s.triggers.as_ref().is_some_and(|t| t.received == 3));
    let t = s.triggers.unwrap();
    assert_eq!((t.foreign, t.malformed, t.oversized, t.accepted), (1, 1, 1, 0), "{t:#?}");
    assert!(s.recording.is_none(), "a refused packet started a take");
    assert_eq!(t.last_refused.as_deref().map(|w| w.starts_with("127.0.0.1: ")), Some(true), "{t:#?}");

    // The master's start: a take under the sanitised name.
    master.send_to(&capture_start("Scene 12 / take 3", 0, 500), &listen).unwrap();
    let s = until(&daemon, "the trigger's take records", |s| s.recording.is_some());
    assert_eq!(s.recording.unwrap().name, "Scene_12_take_3");
    // The same packet again (a resend), with another name: ignored.
    master.send_to(&capture_start("other", 0, 500), &listen).unwrap();
    let t =
        until(&daemon, "the duplicate counted", |s| s.triggers.as_ref().is_some_and(|t| t.duplicates == 1))
            .triggers
            .unwrap();
    let last = t.last.clone().expect("a last message");
    assert_eq!(
        (last.kind.as_str(), last.name.as_deref(), last.packet_id),
        ("CaptureStart", Some("Scene 12 / take 3"), Some(500))
    );
    assert_eq!(last.from, "127.0.0.1");
    std::thread::sleep(Duration::from_millis(200)); // a few frames in the take

    master.send_to(&capture_stop("Scene 12 / take 3", 501), &listen).unwrap();
    let s = until(&daemon, "the trigger's take stops", |s| s.recording.is_none());
    let t = s.triggers.unwrap();
    assert_eq!((t.started, t.stopped, t.accepted, t.duplicates, t.foreign), (1, 1, 2, 1, 1), "{t:#?}");
    let take = std::fs::read(daemon.takes_dir.join("Scene_12_take_3.take")).expect("the take on disk");
    let scan = frond_formats::take::scan_take(&take).unwrap();
    assert!(scan.ended, "the take is not closed");
    assert!(!scan.frames.is_empty(), "the take has no frames");

    // A stop for a take frond is not recording: a count, nothing else.
    master.send_to(&capture_stop("Scene 12 / take 3", 502), &listen).unwrap();
    let t = until(&daemon, "the stray stop counted", |s| {
        s.triggers.as_ref().is_some_and(|t| t.stops_without_take == 1)
    })
    .triggers
    .unwrap();
    assert_eq!(t.stopped, 1);

    // status --json carries the section; doctor names the refused packets.
    let json: serde_json::Value = serde_json::from_str(&daemon.frond_ok(&["status", "--json"])).unwrap();
    assert_eq!(json["triggers"]["foreign"], 1, "{}", json["triggers"]);
    assert_eq!(json["triggers"]["malformed"], 1);
    assert_eq!(json["triggers"]["oversized"], 1);
    let table = daemon.frond_ok(&["status"]);
    assert!(
        table.contains(&format!("triggers     listening on {listen} (from 127.0.0.1); not leading")),
        "{table}"
    );
    let doctor = daemon.frond().arg("doctor").output().unwrap();
    let said =
        String::from_utf8_lossy(&doctor.stdout).into_owned() + &String::from_utf8_lossy(&doctor.stderr);
    assert!(said.contains("ignored 1 packets from hosts outside triggers.allow"), "{said}");
    assert!(said.contains("refused 2 malformed or oversized packets"), "{said}");
}

#[test]
fn a_trigger_start_waits_for_its_delay() {
    let dir = tempfile::tempdir().unwrap();
    let (daemon, listen) = following(dir.path());
    let master = UdpSocket::bind("127.0.0.1:0").unwrap();
    let delay = Duration::from_millis(600);
    let sent = Instant::now();
    master.send_to(&capture_start("late", delay.as_millis() as u32, 7), &listen).unwrap();
    let t = until(&daemon, "the start scheduled", |s| s.triggers.as_ref().is_some_and(|t| t.accepted == 1));
    if sent.elapsed() < delay {
        assert!(t.recording.is_none(), "the take started before its delay");
        assert_eq!(t.triggers.unwrap().scheduled.as_deref(), Some("late"));
    }
    until(&daemon, "the delayed take records", |s| s.recording.is_some());
    assert!(
        sent.elapsed() >= delay,
        "the take started {:?} after the start, before its delay",
        sent.elapsed()
    );
    master.send_to(&capture_stop("late", 8), &listen).unwrap();
    until(&daemon, "the delayed take stops", |s| s.recording.is_none());
    assert!(daemon.takes_dir.join("late.take").is_file());
}

#[test]
fn following_pauses_and_resumes_from_the_command_line_and_a_paused_start_is_counted() {
    let dir = tempfile::tempdir().unwrap();
    let (daemon, listen) = following(dir.path());
    let master = UdpSocket::bind("127.0.0.1:0").unwrap();
    assert!(!triggers(&daemon).paused, "frondd starts following");

    // A take the stage started goes on being followed to its stop after a pause.
    master.send_to(&capture_start("before", 0, 10), &listen).unwrap();
    until(&daemon, "the take starts", |s| s.recording.is_some());
    assert_eq!(
        daemon.frond_ok(&["triggers", "pause"]).trim(),
        format!(
            "capture triggers paused: starts heard on {listen} are counted, not followed \
             (`frond triggers follow` resumes)"
        )
    );
    assert!(triggers(&daemon).paused);
    master.send_to(&capture_stop("before", 11), &listen).unwrap();
    until(&daemon, "the stop still ends the stage's take", |s| s.recording.is_none());

    // Paused: a start (and a delayed one) is heard, counted, and records nothing.
    master.send_to(&capture_start("missed", 0, 12), &listen).unwrap();
    master.send_to(&capture_start("missed-too", 300, 13), &listen).unwrap();
    let s = until(&daemon, "two paused starts counted", |s| {
        s.triggers.as_ref().is_some_and(|t| t.paused_starts == 2)
    });
    assert!(s.recording.is_none(), "a paused start recorded");
    assert!(!daemon.takes_dir.join("missed.take").exists());
    std::thread::sleep(Duration::from_millis(500)); // past the delayed start's time
    assert!(daemon.status().recording.is_none(), "the delayed start recorded while paused");
    assert!(!daemon.takes_dir.join("missed-too.take").exists());
    let table = daemon.frond_ok(&["status"]);
    assert!(
        table.contains(
            "  PAUSED     starts are not followed (2 heard while paused); `frond triggers follow` resumes"
        ),
        "{table}"
    );
    let doctor = daemon.frond().arg("doctor").output().unwrap();
    let said =
        String::from_utf8_lossy(&doctor.stdout).into_owned() + &String::from_utf8_lossy(&doctor.stderr);
    assert!(
        said.contains(&format!(
            "capture triggers are paused: 2 takes the stage started on {listen} were not recorded"
        )),
        "{said}"
    );

    // Following again: the next start records.
    assert_eq!(
        daemon.frond_ok(&["triggers", "follow"]).trim(),
        format!("following capture triggers on {listen}")
    );
    master.send_to(&capture_start("after", 0, 14), &listen).unwrap();
    // (The thread copies its counts to status just after the take starts: wait for both.)
    let s = until(&daemon, "the next take starts", |s| {
        s.recording.is_some() && s.triggers.as_ref().is_some_and(|t| t.started == 2)
    });
    assert_eq!(s.recording.unwrap().name, "after");
    let t = s.triggers.unwrap();
    assert_eq!((t.paused, t.paused_starts, t.started), (false, 2, 2), "{t:#?}");
}

/// A `CaptureStart` as Motive and Rokoko send it, with the master's `TimeCode`, NUL-terminated.
fn capture_start_at(name: &str, timecode: &str, packet_id: u64) -> Vec<u8> {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStart><Name VALUE=\"{name}\"/>\
         <TimeCode VALUE=\"{timecode}\"/><PacketID VALUE=\"{packet_id}\"/><ProcessID VALUE=\"4242\"/></CaptureStart>\0"
    )
    .into_bytes()
}

/// Records a take the master starts with `timecode` for about half a second; its header.
fn master_take(
    daemon: &Daemon,
    listen: &str,
    name: &str,
    timecode: &str,
    id: u64,
) -> frond_motion::take::TakeScan {
    let master = UdpSocket::bind("127.0.0.1:0").unwrap();
    master.send_to(&capture_start_at(name, timecode, id), listen).unwrap();
    until(daemon, "the master's take starts", |s| s.recording.is_some());
    std::thread::sleep(Duration::from_millis(500));
    master.send_to(&capture_stop(name, id + 1), listen).unwrap();
    until(daemon, "the master's take stops", |s| s.recording.is_none());
    let take = std::fs::read(daemon.takes_dir.join(format!("{name}.take"))).unwrap();
    frond_formats::take::scan_take(&take).unwrap()
}

#[test]
fn a_masters_timecode_stamps_the_take_when_no_ltc_is_locked() {
    let dir = tempfile::tempdir().unwrap();
    let listen = format!("127.0.0.1:{}", free_port());
    let config = dir.path().join("stage.toml");
    std::fs::write(&config, format!("[triggers]\nlisten = \"{listen}\"\ntimecode_fps = \"25\"\n")).unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--config", config.to_str().unwrap()]);

    // At 25 fps, as timecode_fps says: the take's first frame is the master's label (or the
    // next, should the first frame come a frame late), and the labels count on from it.
    let scan = master_take(&daemon, &listen, "motive1", "10:00:00:00", 1);
    let anchor = scan
        .header
        .as_ref()
        .and_then(|h| h.stage_clock.clone())
        .expect("the master's TimeCode anchors the take");
    assert_eq!((anchor.label.as_str(), anchor.frame_count, anchor.nominal_fps), ("10:00:00:00", 900_000, 25));
    let lines = daemon.frond_ok(&["take", "export", "motive1", "--fps", "25", "--timecode"]);
    let tcs: Vec<String> = lines
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["tc"].as_str().unwrap().to_string())
        .collect();
    // The first frame was recorded this long after the label's instant (the take's start, a
    // busy machine's moment later): that many 40 ms frames after 10:00:00:00, give or take one.
    let after_ms = scan.frames[0].host_ns.saturating_sub(anchor.host_ns) / 1_000_000;
    let frame = |tc: &str| tc.rsplit(':').next().unwrap().parse::<u64>().unwrap();
    assert!(tcs[0].starts_with("10:00:0"), "{tcs:?}");
    let first = frame(&tcs[0]) + 25 * tcs[0][6..8].parse::<u64>().unwrap();
    assert!(
        first.abs_diff(after_ms / 40) <= 1,
        "first frame {after_ms} ms after the label, exported as {}",
        tcs[0]
    );
    let counts: Vec<u64> = tcs.iter().map(|t| frame(t) + 25 * t[6..8].parse::<u64>().unwrap()).collect();
    assert!(counts.windows(2).all(|w| w[1] == w[0] + 1), "labels count on frame by frame: {tcs:?}");

    // A drop-frame label is 29.97 drop-frame whatever timecode_fps says.
    let scan = master_take(&daemon, &listen, "motive2", "01:00:00;02", 10);
    let anchor = scan.header.and_then(|h| h.stage_clock).expect("a drop-frame label anchors the take");
    // 01:00:00;02: 3,600 s of 30 labels and 2, less the 2 labels dropped in each of the 54
    // minutes of that hour not divisible by 10: 108,002 - 108 = 107,894 frames since midnight.
    assert_eq!(
        (anchor.nominal_fps, anchor.drop_frame, anchor.frame_count),
        (30, true, 107_894),
        "{anchor:?}"
    );
    // "00:00:00:00" means "not used" (Rokoko): no stage clock, the host's time of day.
    let scan = master_take(&daemon, &listen, "rokoko", "00:00:00:00", 20);
    assert_eq!(scan.header.unwrap().stage_clock, None);
}

#[test]
fn without_a_rate_a_masters_whole_frame_timecode_is_not_guessed() {
    let dir = tempfile::tempdir().unwrap();
    let (daemon, listen) = following(dir.path());
    let scan = master_take(&daemon, &listen, "unknown_rate", "10:00:00:00", 1);
    assert_eq!(scan.header.unwrap().stage_clock, None, "24, 25 or 30 fps: frond does not guess");
}

#[test]
fn triggers_cannot_be_followed_when_frondd_listens_for_none() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let out = daemon.frond().args(["triggers", "follow"]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("frondd listens for no capture triggers: start it with --triggers ADDR:PORT"),
        "{err}"
    );
    let out = daemon.frond().args(["triggers", "on"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "a mode that is none is a usage error");
}

#[test]
fn record_start_and_stop_lead_the_stage_and_a_trigger_take_is_not_led() {
    let dir = tempfile::tempdir().unwrap();
    let receiver = UdpSocket::bind("127.0.0.1:0").unwrap();
    receiver.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let lead = receiver.local_addr().unwrap().to_string();
    let listen = format!("127.0.0.1:{}", free_port());
    let daemon = Daemon::start(
        dir.path(),
        &["--source", "in-process", "--triggers", &listen, "--trigger-lead", &lead],
    );
    let pid = daemon.proc.child.id().to_string();
    let mut buf = [0u8; 2048];

    daemon.frond_ok(&["record", "start", "shot-1"]);
    let (n, from) = receiver.recv_from(&mut buf).expect("CaptureStart from frond");
    assert_eq!(from.to_string(), listen, "sent from the listening socket");
    let start = std::str::from_utf8(&buf[..n]).unwrap();
    assert!(
        start.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStart>"),
        "{start:?}"
    );
    assert!(start.ends_with("</CaptureStart>\0"), "NUL-terminated: {start:?}");
    assert!(!start.contains(['\n', '\r', '\t']), "no white space between tokens: {start:?}");
    assert_eq!(value(start, "Name"), Some("shot-1"), "{start}");
    assert_eq!(value(start, "Delay"), Some("0"), "{start}");
    assert_eq!(value(start, "ProcessID"), Some(pid.as_str()), "{start}");
    let start_id: u64 = value(start, "PacketID").expect("a PacketID").parse().unwrap();

    daemon.frond_ok(&["record", "stop"]);
    let (n, _) = receiver.recv_from(&mut buf).expect("CaptureStop from frond");
    let stop = std::str::from_utf8(&buf[..n]).unwrap();
    assert!(
        stop.contains("<CaptureStop RESULT=\"SUCCESS\">") && stop.ends_with("</CaptureStop>\0"),
        "{stop:?}"
    );
    assert_eq!(value(stop, "Name"), Some("shot-1"), "{stop}");
    assert_eq!(value(stop, "PacketID"), Some((start_id + 1).to_string().as_str()), "{stop}");
    let t = triggers(&daemon);
    assert_eq!((t.lead_sent, t.lead_failed), (2, 0), "{t:#?}");

    // A take the stage master starts is followed, not led back to it.
    let master = UdpSocket::bind("127.0.0.1:0").unwrap();
    master.send_to(&capture_start("theirs", 0, 40), &listen).unwrap();
    until(&daemon, "the master's take records", |s| s.recording.is_some());
    master.send_to(&capture_stop("theirs", 41), &listen).unwrap();
    until(&daemon, "the master's take stops", |s| s.recording.is_none());
    receiver.set_read_timeout(Some(Duration::from_millis(300))).unwrap();
    assert!(
        receiver.recv_from(&mut buf).is_err(),
        "frond echoed the master's take: {:?}",
        String::from_utf8_lossy(&buf)
    );
    assert_eq!(triggers(&daemon).lead_sent, 2);
}

#[test]
fn frond_leading_to_its_own_port_ignores_its_echo() {
    let dir = tempfile::tempdir().unwrap();
    let listen = format!("127.0.0.1:{}", free_port());
    let daemon = Daemon::start(
        dir.path(),
        &["--source", "in-process", "--triggers", &listen, "--trigger-lead", &listen],
    );
    daemon.frond_ok(&["record", "start", "own"]);
    let t = until(&daemon, "the echo heard", |s| s.triggers.as_ref().is_some_and(|t| t.own_echoes == 1))
        .triggers
        .unwrap();
    assert_eq!((t.received, t.start_refused), (0, 0), "{t:#?}");
    daemon.frond_ok(&["record", "stop"]);
    let t =
        until(&daemon, "the stop's echo heard", |s| s.triggers.as_ref().is_some_and(|t| t.own_echoes == 2))
            .triggers
            .unwrap();
    assert_eq!((t.received, t.stops_without_take), (0, 0), "{t:#?}");
}

#[test]
fn a_trigger_address_that_is_not_one_is_a_usage_error_naming_the_key() {
    let out = std::process::Command::new(frond_e2e::bin("frondd"))
        .args(["--source", "in-process", "--triggers", "vicon:30", "--trigger-allow", "shogun"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("triggers.listen: \"vicon:30\" is not an address IP:PORT"), "{err}");
    assert!(err.contains("triggers.allow[0]: \"shogun\" is not an IP address"), "{err}");
}

/// On a stage network (two hosts in network namespaces on one switch): the master broadcasts on
/// Vicon's default port 30 to the subnet's broadcast address and frond, listening on
/// `0.0.0.0:30`, follows; frond leads by broadcasting its own take to the same port, which the
/// master hears. Needs root (namespaces, port 30); skipped without.
#[test]
fn triggers_are_broadcast_on_a_stage_network() {
    use frond_e2e::netns::{self, Lan};
    if let Some(why) = netns::unavailable() {
        eprintln!("skipped: {why}");
        return;
    }
    let lan = Lan::new(2);
    let (frond_host, master_host) = (&lan.hosts[0], &lan.hosts[1]);
    let o = frond_host.addr.octets();
    let broadcast = format!("{}.{}.{}.255:30", o[0], o[1], o[2]);
    let dir = tempfile::tempdir().unwrap();
    let allow = master_host.addr.to_string();
    let daemon = Daemon::start_on(
        frond_host,
        dir.path(),
        &[
            "--source",
            "in-process",
            "--triggers",
            "0.0.0.0:30",
            "--trigger-allow",
            &allow,
            "--trigger-lead",
            &broadcast,
        ],
    );
    let to = broadcast.clone();
    let master = master_host
        .run_inside(move || {
            let socket = UdpSocket::bind("0.0.0.0:30").unwrap();
            socket.set_broadcast(true).unwrap();
            socket.send_to(&capture_start("stage take", 0, 9000), &to).unwrap();
            socket
        })
        .join()
        .unwrap();
    let s = until(&daemon, "the broadcast start followed", |s| s.recording.is_some());
    assert_eq!(s.recording.unwrap().name, "stage_take");
    master.send_to(&capture_stop("stage take", 9001), &broadcast).unwrap();
    until(&daemon, "the broadcast stop followed", |s| s.recording.is_none());
    assert_eq!(triggers(&daemon).last.unwrap().from, allow);

    // frond leads: its broadcast reaches the master (and comes back to frond, ignored).
    master.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    daemon.frond_ok(&["record", "start", "frond-take"]);
    let mut buf = [0u8; 2048];
    // The master hears its own broadcasts too: the first datagram from frond's host is frond's.
    let n = loop {
        let (n, from) = master.recv_from(&mut buf).expect("frond's broadcast CaptureStart");
        if from.ip() == frond_host.addr {
            break n;
        }
    };
    let start = std::str::from_utf8(&buf[..n]).unwrap();
    assert!(start.contains("<CaptureStart>") && value(start, "Name") == Some("frond-take"), "{start:?}");
    daemon.frond_ok(&["record", "stop"]);
    let t = triggers(&daemon);
    assert_eq!((t.lead_sent, t.start_refused, t.started), (2, 0, 1), "{t:#?}");
}
