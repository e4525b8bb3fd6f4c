//! `frond take list|export|repair` on take files built with the motion crate's codec.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, SystemTime};

use frond_formats::jsonl::{parse_pose_line, write_pose_line};
use frond_formats::take::{TakeRecord, encode_file_start, encode_record};
use frond_motion::{HandSample, PoseFrame, TakeFrame, TakeHeader};
use frond_protocol::{ElementId, PoseFlags};

fn frond(takes: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_frond"));
    c.env_remove("FROND_SOCKET_DIR").env("FROND_TAKES_DIR", takes);
    c
}

fn text(b: &[u8]) -> String {
    String::from_utf8(b.to_vec()).unwrap()
}

fn ok(out: Output) -> String {
    assert!(out.status.success(), "status {:?}, stderr {}", out.status, text(&out.stderr));
    text(&out.stdout)
}

/// Root pitch of the test take at `t`: 10 degrees per second from t = 2 s.
fn pitch(t: f64) -> f32 {
    (10.0 * (t - 2.0)) as f32
}

fn frame(seq: u64, t: f64, flags: PoseFlags) -> TakeFrame {
    let p = pitch(t);
    TakeFrame {
        seq,
        device_time_us: (t * 1e6).round() as u64,
        host_ns: 1_000_000 * seq,
        flags: flags.0,
        element: ElementId::GLOBAL,
        pose: PoseFrame { t, joints_deg: [[p, -p, 0.0], [p / 2.0, 0.0, 0.0], [0.0; 3], [0.0, 0.0, 1.5]] },
        hand: HandSample { t, wrist_deg: [p, -p, 1.5], thumb_deg: [0.0; 3] },
    }
}

/// The file start and header record of a grass take named `name`, recorded at `tick_rate_hz`.
fn take_start(name: &str, tick_rate_hz: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    encode_file_start(&mut bytes);
    encode_record(
        &TakeRecord::Header(TakeHeader {
            created_unix_s: 1_700_000_000,
            joint_names: ["root", "lower", "middle", "tip"].map(String::from).to_vec(),
            ..TakeHeader::offline(name, "grass", tick_rate_hz)
        }),
        &mut bytes,
    );
    bytes
}

/// 101 samples at 100 Hz from t = 2 s to 3 s, each followed by a held repeat (the daemon at
/// 200 Hz), one marker, and an End record when `end`.
fn build_take(name: &str, end: bool) -> (Vec<u8>, Vec<TakeFrame>) {
    let mut bytes = take_start(name, 200);
    let mut frames = Vec::new();
    for i in 0..=100u64 {
        let t = 2.0 + i as f64 / 100.0;
        frames.push(frame(2 * i, t, PoseFlags::FILTERED));
        frames.push(frame(2 * i + 1, t, PoseFlags::HELD));
    }
    for f in &frames {
        encode_record(&TakeRecord::Frame(*f), &mut bytes);
    }
    encode_record(&TakeRecord::Marker { seq: 40, label: "gust".into() }, &mut bytes);
    if end {
        encode_record(&TakeRecord::End { frames: frames.len() as u64 }, &mut bytes);
    }
    (bytes, frames)
}

fn setup() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let takes = dir.path().join("takes");
    std::fs::create_dir(&takes).unwrap();
    (dir, takes)
}

fn age(path: &Path) {
    let f = std::fs::File::options().write(true).open(path).unwrap();
    f.set_modified(SystemTime::now() - Duration::from_secs(60)).unwrap();
}

#[test]
fn export_prints_each_sample_once_with_its_recorded_pose() {
    let (_d, takes) = setup();
    let (bytes, frames) = build_take("breeze", true);
    std::fs::write(takes.join("breeze.take"), bytes).unwrap();
    let out = ok(frond(&takes).args(["take", "export", "breeze", "--jsonl"]).output().unwrap());
    // Each line is the recorded pose as write_pose_line prints it. (Compared as text: the JSON
    // reader is not bit-exact for every f64, e.g. 2.2800000000000002 reads back as 2.28.)
    let want: Vec<String> = frames
        .iter()
        .filter(|f| f.flags & PoseFlags::HELD.0 == 0)
        .map(|f| {
            let mut s = String::new();
            write_pose_line(&f.pose, None, &mut s);
            s
        })
        .collect();
    let got: Vec<&str> = out.lines().collect();
    assert_eq!(got.len(), 101);
    assert_eq!(got, want);
    for (line, f) in got.iter().zip(frames.iter().step_by(2)) {
        let p = parse_pose_line(line).unwrap();
        assert_eq!(p.joints_deg, f.pose.joints_deg);
        assert!((p.t - f.pose.t).abs() < 1e-12);
    }
    assert!(out.lines().next().unwrap().starts_with(r#"{"t":2.0,"joints":[[0.0,-0.0,0.0]"#), "{out}");

    let all =
        ok(frond(&takes).args(["take", "export", "breeze", "--jsonl", "--include-held"]).output().unwrap());
    assert_eq!(all.lines().count(), 202);
}

#[test]
fn export_at_30_fps_interpolates_from_zero() {
    let (_d, takes) = setup();
    let (bytes, _) = build_take("breeze", true);
    std::fs::write(takes.join("breeze.take"), bytes).unwrap();
    let out =
        ok(frond(&takes).args(["take", "export", "breeze", "--jsonl", "--fps", "30"]).output().unwrap());
    let got: Vec<PoseFrame> = out.lines().map(|l| parse_pose_line(l).unwrap()).collect();
    // 1 s at 30 FPS: frames k/30 for k = 0..=30. The root pitch is linear in time (10 deg/s).
    assert_eq!(got.len(), 31);
    for (k, p) in got.iter().enumerate() {
        let t = k as f64 / 30.0;
        assert!((p.t - t).abs() < 1e-12, "frame {k}: t {}", p.t);
        let want = 10.0 * t as f32;
        assert!((p.joints_deg[0][0] - want).abs() < 1e-4, "frame {k}: {} vs {want}", p.joints_deg[0][0]);
        assert!((p.joints_deg[0][1] + want).abs() < 1e-4);
        assert_eq!(p.joints_deg[3][2], 1.5);
    }
}

#[test]
fn list_shows_complete_open_torn_damaged_empty_and_corrupt_takes() {
    let (_d, takes) = setup();
    let (done, _) = build_take("a-done", true);
    std::fs::write(takes.join("a-done.take"), &done).unwrap();
    let (open, _) = build_take("b-open", false);
    std::fs::write(takes.join("b-open.take"), &open).unwrap();
    let mut torn = open.clone();
    torn.extend_from_slice(&[200, 0, 0, 0, 9, 9, 9]);
    std::fs::write(takes.join("c-torn.take"), &torn).unwrap();
    let mut damaged = done.clone();
    damaged[take_start("a-done", 200).len() + 127 * 10 + 60] ^= 0x55;
    std::fs::write(takes.join("d-damaged.take"), &damaged).unwrap();
    std::fs::write(takes.join("e-empty.take"), "").unwrap();
    std::fs::write(takes.join("f-corrupt.take"), "not a take at all").unwrap();
    std::fs::write(takes.join("notes.txt"), "not a take").unwrap();

    let json = ok(frond(&takes).args(["take", "list", "--json"]).output().unwrap());
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let rows = v.as_array().unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["a-done", "b-open", "c-torn", "d-damaged", "e-empty", "f-corrupt"]);
    let states: Vec<&str> = rows.iter().map(|r| r["state"].as_str().unwrap()).collect();
    assert_eq!(states, ["complete", "open", "torn", "damaged", "empty", "corrupt"]);
    assert_eq!(rows[0]["frames"], 202);
    assert_eq!(rows[0]["duration_s"].as_f64().unwrap(), 1.0);
    assert_eq!(rows[0]["size_bytes"], done.len() as u64);
    assert_eq!(rows[0]["markers"], 1);
    assert_eq!(rows[0]["rig"], "grass");
    assert_eq!(rows[2]["torn_bytes"], 7);
    // One frame record (127 bytes) is lost; the other 201 frames are listed.
    assert_eq!(rows[3]["frames"], 201);
    assert_eq!(rows[3]["skipped_bytes"], 127);
    assert!(rows[3]["damage"].as_str().unwrap().contains("1 frame lost"), "{json}");
    assert_eq!(rows[4]["frames"], 0);
    assert!(rows[5]["error"].as_str().unwrap().contains("not a frond take"), "{json}");

    let table = ok(frond(&takes).args(["take", "list"]).output().unwrap());
    let line = table.lines().find(|l| l.starts_with("a-done")).unwrap();
    let cols: Vec<&str> = line.split_whitespace().collect();
    assert_eq!(cols[..3], ["a-done", "202", "1.00s"], "{table}");
    assert!(table.contains("torn (7 bytes; `frond take repair c-torn`)"), "{table}");
    assert!(table.contains("damaged: 1 damaged stretch skipped"), "{table}");
    assert!(table.contains("`frond take repair d-damaged`"), "{table}");
}

#[test]
fn list_of_a_missing_directory_is_empty() {
    let (_d, takes) = setup();
    let missing = takes.join("none");
    let json = ok(frond(&missing).args(["take", "list", "--json"]).output().unwrap());
    assert_eq!(json.trim(), "[]");
    let table = ok(frond(&missing).args(["take", "list"]).output().unwrap());
    assert!(table.starts_with("no takes in"), "{table}");
}

#[test]
fn repair_cuts_a_torn_tail_then_the_take_is_complete() {
    let (_d, takes) = setup();
    let (open, frames) = build_take("gust", false);
    let mut torn = open.clone();
    torn.extend_from_slice(&[10, 0, 0, 0, 1, 2, 3, 4, 5]);
    let path = takes.join("gust.take");
    std::fs::write(&path, &torn).unwrap();

    // Export still works, with a warning.
    let out = frond(&takes).args(["take", "export", "gust", "--jsonl"]).output().unwrap();
    assert!(out.status.success());
    assert!(text(&out.stderr).contains("torn record (9 bytes)"), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout).lines().count(), 101);

    // A freshly written file may still be recording: refused.
    let out = frond(&takes).args(["take", "repair", "gust"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("may still be recording"), "{}", text(&out.stderr));

    age(&path);
    let msg = ok(frond(&takes).args(["take", "repair", "gust"]).output().unwrap());
    assert!(
        msg.contains("dropped 9 torn bytes at the end; kept 202 frames, closed with an End record"),
        "{msg}"
    );
    let mut want = open;
    encode_record(&TakeRecord::End { frames: frames.len() as u64 }, &mut want);
    assert_eq!(std::fs::read(&path).unwrap(), want);
    // No temporary files left behind.
    assert_eq!(std::fs::read_dir(&takes).unwrap().count(), 1);

    // Right after (the file was just written): a closed take is not "still recording".
    let msg = ok(frond(&takes).args(["take", "repair", "gust"]).output().unwrap());
    assert!(msg.contains("nothing to repair"), "{msg}");
}

#[test]
fn damaged_takes_are_read_around_the_damage_and_repaired_without_it() {
    let (_d, takes) = setup();
    let (bytes, frames) = build_take("bad", true);
    // Frame records are 127 bytes after the header: flip a bit in frame 10 (seq 10, a sample).
    let at = take_start("bad", 200).len() + 127 * 10;
    let mut damaged = bytes.clone();
    damaged[at + 60] ^= 0x04;
    let path = takes.join("bad.take");
    std::fs::write(&path, &damaged).unwrap();

    let out = frond(&takes).args(["take", "export", "bad", "--jsonl"]).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    assert!(err.contains(&path.display().to_string()), "{err}");
    assert!(err.contains(&format!("127 bytes at offset {at} (checksum mismatch)")), "{err}");
    assert!(err.contains("1 frame lost"), "{err}");
    let want: Vec<String> = frames
        .iter()
        .filter(|f| f.flags & PoseFlags::HELD.0 == 0 && f.seq != 10)
        .map(|f| {
            let mut s = String::new();
            write_pose_line(&f.pose, None, &mut s);
            s
        })
        .collect();
    assert_eq!(text(&out.stdout).lines().collect::<Vec<_>>(), want);

    // Freshly written but closed with an End record: repaired at once, saying what it dropped.
    let msg = ok(frond(&takes).args(["take", "repair", "bad"]).output().unwrap());
    assert!(
        msg.contains(&format!(
            "dropped 127 bytes at offset {at} (checksum mismatch); 1 frame lost; kept 201 frames"
        )),
        "{msg}"
    );
    let mut repaired = take_start("bad", 200);
    for f in frames.iter().filter(|f| f.seq != 10) {
        encode_record(&TakeRecord::Frame(*f), &mut repaired);
    }
    encode_record(&TakeRecord::Marker { seq: 40, label: "gust".into() }, &mut repaired);
    encode_record(&TakeRecord::End { frames: 201 }, &mut repaired);
    assert_eq!(std::fs::read(&path).unwrap(), repaired);
    let msg = ok(frond(&takes).args(["take", "repair", "bad"]).output().unwrap());
    assert!(msg.contains("nothing to repair"), "{msg}");

    std::fs::write(&path, "").unwrap();
    let out = frond(&takes).args(["take", "repair", "bad"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("empty (0 bytes)"), "{}", text(&out.stderr));

    let out = frond(&takes).args(["take", "export", "nope", "--jsonl"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("no take named \"nope\""), "{}", text(&out.stderr));

    let out = frond(&takes).args(["take", "export", "../etc/passwd"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));

    std::fs::write(&path, &bytes).unwrap();
    let out = frond(&takes).args(["take", "export", "bad", "--fps", "0"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));

    std::fs::write(takes.join("text.take"), "hello").unwrap();
    let out = frond(&takes).args(["take", "export", "text"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("not a frond take"), "{}", text(&out.stderr));
}

#[test]
fn export_accepts_a_path() {
    let (_d, takes) = setup();
    let (bytes, _) = build_take("elsewhere", true);
    let path = takes.join("elsewhere.take");
    std::fs::write(&path, bytes).unwrap();
    let out = ok(Command::new(env!("CARGO_BIN_EXE_frond"))
        .env_remove("FROND_TAKES_DIR")
        .args(["take", "export", "--jsonl"])
        .arg(&path)
        .output()
        .unwrap());
    assert_eq!(out.lines().count(), 101);

    // What is there but is not a take file is named as such, not as a bad name or a missing take.
    std::fs::create_dir(takes.join("sub.take")).unwrap();
    let sub = takes.join("sub.take").display().to_string();
    let missing = takes.join("gone.take").display().to_string();
    for (arg, says) in [
        ("/dev/null", "/dev/null is a device, not a take file".to_string()),
        (sub.as_str(), format!("{sub} is a directory, not a take file")),
        ("sub", format!("{sub} is a directory, not a take file")),
        (missing.as_str(), format!("no take file {missing}: it does not exist")),
    ] {
        let out = frond(&takes).args(["take", "export", "--jsonl", arg]).output().unwrap();
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(if arg == missing { 2 } else { 1 }), "{arg}: {err}");
        assert!(err.contains(&says), "{arg}: {err}");
    }
}

/// A take of `n` frames at `fps` whose times carry six decimals, as a recorded take's do.
fn six_decimal_take(name: &str, n: usize, fps: f64) -> Vec<u8> {
    let mut bytes = take_start(name, fps as u32);
    for k in 0..n {
        let t: f64 = format!("{:.6}", k as f64 / fps).parse().unwrap();
        encode_record(&TakeRecord::Frame(frame(k as u64, t, PoseFlags::FILTERED)), &mut bytes);
    }
    encode_record(&TakeRecord::End { frames: n as u64 }, &mut bytes);
    bytes
}

#[test]
fn identity_resampling_keeps_every_frame_through_export_and_import() {
    // The issue's case is 200 frames at 30 FPS (last t = 6.633333, which rounds down); the
    // others round up, land exactly, or are the shortest takes.
    let (_d, takes) = setup();
    let run = |args: &[&str]| ok(frond(&takes).args(args).output().unwrap());
    for (fps, n) in [30, 24, 25, 60]
        .iter()
        .flat_map(|&f| [1, 2, 3, 89, 90, 199, 200, 201, 300, 301, 397, 400].map(|n| (f, n)))
    {
        let fps_s = fps.to_string();
        std::fs::write(takes.join("src.take"), six_decimal_take("src", n, fps as f64)).unwrap();
        let exported = run(&["take", "export", "src", "--jsonl"]);
        assert_eq!(exported.lines().count(), n);
        let file = takes.join("src.jsonl");
        std::fs::write(&file, &exported).unwrap();
        run(&["take", "import", file.to_str().unwrap(), "imp", "--force"]);
        for args in [
            &["take", "export", "imp", "--jsonl", "--fps", &fps_s][..],
            &["take", "retime", "imp", "--speed", "1", "--fps", &fps_s, "--jsonl"],
            &["take", "resample", "imp", "--fps", &fps_s, "--jsonl"],
            &["take", "filter", "imp", "--filter", "lowpass", "--fps", &fps_s, "--jsonl"],
        ] {
            let got = run(args).lines().count();
            assert_eq!(got, n, "{n} frames at {fps} FPS: `frond {}` gives {got}", args.join(" "));
        }
    }
}

#[test]
fn a_gap_in_time_is_a_discontinuity_and_resampling_is_bounded() {
    let (_d, takes) = setup();
    // Two frames at t = 0 and t = 1e9 (issue 14, point 7: was 16.7 million lines).
    let mut bytes = take_start("jump", 30);
    encode_record(&TakeRecord::Frame(frame(0, 0.0, PoseFlags::FILTERED)), &mut bytes);
    encode_record(&TakeRecord::Frame(frame(1, 1e9, PoseFlags::FILTERED)), &mut bytes);
    encode_record(&TakeRecord::End { frames: 2 }, &mut bytes);
    std::fs::write(takes.join("jump.take"), &bytes).unwrap();
    let out = frond(&takes).args(["take", "export", "jump", "--fps", "30"]).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let lines: Vec<PoseFrame> = text(&out.stdout).lines().map(|l| parse_pose_line(l).unwrap()).collect();
    assert_eq!(lines.len(), 2);
    assert_eq!(lines[0].joints_deg, frame(0, 0.0, PoseFlags::FILTERED).pose.joints_deg);
    assert_eq!(lines[1].joints_deg, frame(1, 1e9, PoseFlags::FILTERED).pose.joints_deg);
    assert!((lines[1].t - 1.0 / 30.0).abs() < 1e-9);
    let err = text(&out.stderr);
    assert!(err.contains("1 step in time longer than 1 s") && err.contains("discontinuity"), "{err}");
    // The same warning into a stderr whose reader has gone: lost, not a panic (was exit 101).
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = frond(&takes).args(["take", "export", "jump", "--fps", "30"]).stderr(writer).output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(text(&out.stdout).lines().count(), 2);

    // 121 frames a second apart (no discontinuity) at 10000 FPS: 1,200,001 frames, past the
    // export limit of 1,080,000: refused before anything is resampled, unless --force.
    let mut bytes = take_start("long", 1);
    for k in 0..=120u64 {
        encode_record(&TakeRecord::Frame(frame(k, k as f64, PoseFlags::FILTERED)), &mut bytes);
    }
    std::fs::write(takes.join("long.take"), &bytes).unwrap();
    let out = frond(&takes).args(["take", "export", "long", "--fps", "10000"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stdout.is_empty());
    let err = text(&out.stderr);
    assert!(
        err.contains("1200001 frames, more than the limit of 1080000") && err.contains("--force"),
        "{err}"
    );
    let status = frond(&takes)
        .args(["take", "export", "long", "--fps", "10000", "--force"])
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
}

#[test]
fn take_tools_refuse_an_output_past_the_limit_instead_of_cutting_it_short() {
    let (_d, takes) = setup();
    // 3.5 s at 30 FPS (106 frames). At --speed 1e-5 it lasts 350,000 s: 10,500,001 frames, past
    // the 1,080,000 limit; at 1e-9, 3.5e9 s and 105,000,000,001 frames, past even the hard
    // 16,777,216 where the output was once cut silently (exit 0). Both exit 1, as resampling.
    std::fs::write(takes.join("short.take"), six_decimal_take("short", 106, 30.0)).unwrap();
    let run = |args: &[&str]| frond(&takes).args(args).output().unwrap();
    let out = run(&["take", "retime", "short", "--speed", "1e-5"]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("lasts 350000.0 s: 10500001 frames at 30 FPS, more than 1080000; pass --force"),
        "{err}"
    );
    let out = run(&["take", "retime", "short", "--speed", "1e-9", "--force"]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "lasts 3500000000.0 s: 105000000001 frames at 30 FPS, more than the 16777216 any output may have"
        ),
        "{err}"
    );
    // A loop as long as asked: 86,400 s at 1000 FPS is 86,400,001 frames.
    let out = run(&["take", "loop", "short", "--duration", "86400", "--fps", "1000", "--force"]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("the loop lasts 86400.0 s: 86400001 frames at 1000 FPS, more than the 16777216"),
        "{err}"
    );
    assert!(!takes.join("short-retime.take").exists());

    // Resampling: 1201 frames a second apart at 1000 FPS is 1,200,001 frames.
    let mut bytes = take_start("long", 1);
    for k in 0..=1200u64 {
        encode_record(&TakeRecord::Frame(frame(k, k as f64, PoseFlags::FILTERED)), &mut bytes);
    }
    std::fs::write(takes.join("long.take"), &bytes).unwrap();
    for tool in [
        &["take", "resample", "long", "--fps", "1000"][..],
        &["take", "filter", "long", "--filter", "lowpass", "--fps", "1000"],
    ] {
        let out = run(tool);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{tool:?}: {err}");
        assert!(
            err.contains("1200001 frames, more than the limit of 1080000") && err.contains("--force"),
            "{err}"
        );
    }
    assert_eq!(std::fs::read_dir(&takes).unwrap().count(), 2, "no take was written");
}

#[test]
fn a_takes_rig_name_is_looked_up_among_the_embedded_rigs_never_opened_as_a_path() {
    let (_d, takes) = setup();
    let with_rig = |name: &str, rig: &str| {
        let mut bytes = Vec::new();
        encode_file_start(&mut bytes);
        let header = TakeHeader { created_unix_s: 1_700_000_000, ..TakeHeader::offline(name, rig, 30) };
        encode_record(&TakeRecord::Header(header), &mut bytes);
        for k in 0..30u64 {
            encode_record(&TakeRecord::Frame(frame(k, k as f64 / 30.0, PoseFlags::FILTERED)), &mut bytes);
        }
        encode_record(&TakeRecord::End { frames: 30 }, &mut bytes);
        std::fs::write(takes.join(format!("{name}.take")), bytes).unwrap();
    };
    // A rig that was loaded from a file keeps only its name; one that names a device (a hostile
    // take) must not make export read it.
    with_rig("mine", "my-shrub");
    with_rig("dev", "/dev/zero");
    with_rig("esc", "a\u{1b}[31mRED\nline2");
    let bvh = takes.join("x.bvh");
    for (take, rig) in [("mine", "my-shrub"), ("dev", "/dev/zero")] {
        let out = frond(&takes).args(["take", "export", take, "--bvh", "-o"]).arg(&bvh).output().unwrap();
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!(": rig {rig:?} is not an embedded rig (grass, ")), "{err}");
        assert!(err.contains("give that file with --rig FILE") && !err.contains("device"), "{err}");
    }
    assert!(!bvh.exists());
    ok(frond(&takes)
        .args(["take", "export", "mine", "--bvh", "--rig", "grass", "-o"])
        .arg(&bvh)
        .output()
        .unwrap());
    assert!(bvh.is_file());
    // take list shows a hostile rig name escaped, on its own line.
    let list = ok(frond(&takes).args(["take", "list"]).output().unwrap());
    assert!(!list.contains('\u{1b}'), "{list:?}");
    let line = list.lines().find(|l| l.starts_with("esc ")).unwrap();
    assert!(line.ends_with("a\\u{1b}[31mRED\\nline2"), "{line:?}");
}

#[test]
fn non_finite_values_are_refused_by_frame() {
    let (_d, takes) = setup();
    for (bad, name) in [(f32::NAN, "nan"), (f32::INFINITY, "inf")] {
        let mut bytes = take_start(name, 100);
        for k in 0..5u64 {
            let mut f = frame(k, 2.0 + k as f64 / 100.0, PoseFlags::FILTERED);
            if k == 3 {
                f.pose.joints_deg[1][0] = bad;
            }
            encode_record(&TakeRecord::Frame(f), &mut bytes);
        }
        encode_record(&TakeRecord::End { frames: 5 }, &mut bytes);
        std::fs::write(takes.join(format!("{name}.take")), &bytes).unwrap();
        let out = frond(&takes).args(["take", "export", name]).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{name}: {}", text(&out.stdout));
        assert!(out.stdout.is_empty());
        let err = text(&out.stderr);
        assert!(err.contains("frame 3 (seq 3") && err.contains("pose joint 1"), "{err}");
        // Repair drops exactly that frame, then the take exports.
        let msg = ok(frond(&takes).args(["take", "repair", name]).output().unwrap());
        assert!(
            msg.contains("frame 3 (seq 3) holds") && msg.contains("1 frame lost; kept 4 frames"),
            "{msg}"
        );
        let lines = ok(frond(&takes).args(["take", "export", name]).output().unwrap());
        assert_eq!(lines.lines().count(), 4);
    }
}
