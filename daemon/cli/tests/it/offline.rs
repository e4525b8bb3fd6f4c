//! `frond` commands that need no daemon, run as the real binary.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use frond_formats::jsonl::parse_pose_line;
use frond_motion::PoseFrame;

fn frond() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_frond"));
    c.env_remove("FROND_SOCKET_DIR").env_remove("FROND_TAKES_DIR");
    c
}

fn run(cmd: &mut Command, stdin: &str) -> Output {
    let mut child = cmd.stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    child.stdin.take().unwrap().write_all(stdin.as_bytes()).unwrap();
    child.wait_with_output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8(b.to_vec()).unwrap()
}

/// A rig with unequal scales and tau = 1, and no filter.
const RIG: &str = r#"
name = "test-reed"
tau = 1
thumb_range_deg = [60.0, 70.0, 60.0]
filter = "none"
[[joints]]
height_m = 0.0
s_pitch = 0.5
s_yaw = 2.0
s_roll = 1.0
[[joints]]
height_m = 0.1
s_pitch = 1.0
s_yaw = 1.0
s_roll = 1.0
[[joints]]
height_m = 0.2
s_pitch = 0.5
s_yaw = 0.5
s_roll = 1.0
[[joints]]
height_m = 0.3
s_pitch = 2.0
s_yaw = 1.0
s_roll = 0.5
"#;

const CALIBRATION: &str = r#"
id = "tester"
neutral_wrist_deg = [10.0, -4.0, 2.0]
neutral_thumb_deg = [2.0, 4.0, 8.0]
thumb_range_deg = [40.0, 20.0, 16.0]
"#;

struct Files {
    _dir: tempfile::TempDir,
    rig: PathBuf,
    calibration: PathBuf,
    root: PathBuf,
}

fn files() -> Files {
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("reed.toml");
    let calibration = dir.path().join("tester.toml");
    std::fs::write(&rig, RIG).unwrap();
    std::fs::write(&calibration, CALIBRATION).unwrap();
    Files { root: dir.path().to_owned(), _dir: dir, rig, calibration }
}

fn poses(stdout: &[u8]) -> Vec<PoseFrame> {
    text(stdout).lines().map(|l| parse_pose_line(l).unwrap()).collect()
}

#[test]
fn map_with_a_calibration_matches_hand_computed_poses() {
    let f = files();
    let hand = concat!(
        "{\"t\":0.0,\"wrist\":[30,6,12],\"thumb\":[22,14,12]}\n",
        "{\"t\":0.5,\"wrist\":[-10,-4,-6],\"thumb\":[2,-6,0]}\n",
    );
    let out = run(frond().args(["map", "--rig"]).arg(&f.rig).arg("--calibration").arg(&f.calibration), hand);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // Line 1: W = (20, 10, 10), G = (20, 10, 4), G/G_R = (0.5, 0.5, 0.25).
    //   Eq. 2: P0 = (0.5*20, 2*10) = (10, 20). Eq. 3: P1 = 1*(10, 20)*0.5 = (5, 10),
    //   P2 = 0.5*(10, 20)*0.5 = (2.5, 5), P3 = (2*10, 1*20)*0.25 = (5, 5).
    //   Eq. 4, tau 1: only joint 3 rolls, 0.5*10 = 5.
    // Line 2: W = (-20, 0, -8), G = (0, -10, -8), G/G_R = (0, -0.5, -0.5).
    //   P0 = (-10, 0); P1 = (0, 0); P2 = 0.5*(-10)*(-0.5) = 2.5; P3 = 2*(-10)*(-0.5) = 10;
    //   roll 3 = 0.5*(-8) = -4.
    let expected = vec![
        PoseFrame {
            t: 0.0,
            joints_deg: [[10.0, 20.0, 0.0], [5.0, 10.0, 0.0], [2.5, 5.0, 0.0], [5.0, 5.0, 5.0]],
        },
        PoseFrame {
            t: 0.5,
            joints_deg: [[-10.0, 0.0, 0.0], [0.0, 0.0, 0.0], [2.5, 0.0, 0.0], [10.0, 0.0, -4.0]],
        },
    ];
    assert_eq!(poses(&out.stdout), expected);
    assert_eq!(
        text(&out.stdout).lines().next().unwrap(),
        r#"{"t":0.0,"joints":[[10.0,20.0,0.0],[5.0,10.0,0.0],[2.5,5.0,0.0],[5.0,5.0,5.0]]}"#
    );
    assert!(out.stderr.is_empty(), "{}", text(&out.stderr));
}

#[test]
fn map_drives_the_shrub_to_its_bend_range_for_two_different_wrists() {
    // shrub.toml: bend_range_deg = [12, 12], s_pitch = s_yaw = 0.2, 0.4, 0.5, 0.6, tau 1.
    // Ann: pitch -30..50 around 10 (reach 40 / 40), yaw -25..15 around -5 (20 / 20).
    // Ben: pitch -75..45 around -15 (60 / 60), yaw -10..50 around 10 (20 / 40).
    // Each at pitch max, yaw min, thumb bent through its range (G_i / G_R_i = 1):
    //   P0 = (12, -12), P1 = 0.4 P0, P2 = 0.5 P0, P3 = 0.6 P0; roll at neutral = 0.
    // Without wrist ranges Ann's +40 would bend 0.2 * 40 = 8 and Ben's +60 12.
    let dir = tempfile::tempdir().unwrap();
    let shrub = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/plants/shrub.toml");
    let want = [[12.0, -12.0, 0.0], [4.8, -4.8, 0.0], [6.0, -6.0, 0.0], [7.2, -7.2, 0.0]];
    for (id, neutral, ranges, extreme) in [
        ("ann", "[10, -5, 0]", "[[-30, 50], [-25, 15], [-60, 60]]", "[50,-25,0]"),
        ("ben", "[-15, 10, 0]", "[[-75, 45], [-10, 50], [-60, 60]]", "[45,-10,0]"),
    ] {
        let cal = dir.path().join(format!("{id}.toml"));
        std::fs::write(
            &cal,
            format!(
                "id = \"{id}\"\nneutral_wrist_deg = {neutral}\nneutral_thumb_deg = [0, 0, 0]\n\
                 thumb_range_deg = [50, 60, 70]\nwrist_range_deg = {ranges}\n"
            ),
        )
        .unwrap();
        let hand = format!("{{\"t\":0.0,\"wrist\":{extreme},\"thumb\":[50,60,70]}}\n");
        // The rig file, and the same rig by its embedded name.
        for rig in [shrub.as_os_str(), "shrub".as_ref()] {
            let out = run(
                frond().args(["map", "--filter", "none", "--rig"]).arg(rig).arg("--calibration").arg(&cal),
                &hand,
            );
            assert!(out.status.success(), "{id} {rig:?}: {}", text(&out.stderr));
            let p = poses(&out.stdout);
            assert_eq!(p.len(), 1);
            let close = p[0]
                .joints_deg
                .iter()
                .flatten()
                .zip(want.iter().flatten())
                .all(|(a, b)| (a - b).abs() < 1e-4);
            assert!(close, "{id} {rig:?}: {:?}", p[0].joints_deg);
        }
    }
}

#[test]
fn map_without_calibration_uses_zero_neutral_and_the_rig_ranges() {
    let f = files();
    // Rig ranges (60, 70, 60): G/G_R = (0.5, 0.5, 0.25).
    // P0 = (0.5*30, 2*6) = (15, 12); P1 = (7.5, 6); P2 = 0.5*(15, 12)*0.5 = (3.75, 3);
    // P3 = (2*15, 1*12)*0.25 = (7.5, 3), roll 0.5*12 = 6.
    let hand = "{\"t\":1.25,\"wrist\":[30,6,12],\"thumb\":[30,35,15]}\n";
    let input = f.root.join("hand.jsonl");
    std::fs::write(&input, hand).unwrap();
    let out = run(frond().args(["map", "--rig"]).arg(&f.rig).arg("--input").arg(&input), "");
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        poses(&out.stdout),
        vec![PoseFrame {
            t: 1.25,
            joints_deg: [[15.0, 12.0, 0.0], [7.5, 6.0, 0.0], [3.75, 3.0, 0.0], [7.5, 3.0, 6.0]]
        }]
    );
}

#[test]
fn map_filter_option_overrides_the_rig() {
    let f = files();
    // A step in wrist pitch: unfiltered the second root pitch is 0.5*40 = 20; a low-pass lags.
    let hand =
        "{\"t\":0,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n{\"t\":0.01,\"wrist\":[40,0,0],\"thumb\":[0,0,0]}\n";
    let none = run(frond().args(["map", "--filter", "none", "--rig"]).arg(&f.rig), hand);
    let low = run(frond().args(["map", "--filter", "lowpass:cutoff_hz=2", "--rig"]).arg(&f.rig), hand);
    assert!(none.status.success() && low.status.success(), "{}", text(&low.stderr));
    assert_eq!(poses(&none.stdout)[1].joints_deg[0][0], 20.0);
    let lagged = poses(&low.stdout)[1].joints_deg[0][0];
    assert!(lagged > 0.0 && lagged < 20.0, "{lagged}");
    let bare = run(frond().args(["map", "--filter", "one-euro", "--rig"]).arg(&f.rig), hand);
    assert!(bare.status.success(), "{}", text(&bare.stderr));
}

#[test]
fn map_reports_every_bad_line_writes_the_good_ones_and_fails() {
    let f = files();
    let hand = concat!(
        "{\"t\":0.0,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n",
        "{\"t\":0.1,\"wrist\":[0,0],\"thumb\":[0,0,0]}\n",
        "{\"t\":0.2,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n",
        "{\"t\":0.3,\"wrist\":[0,0,0],\"thumb\":[0,\"x\",0]}\n",
        "{\"t\":0.4,\"wrist\":[0,0,0]}\n",
        "{\"t\":0.5,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n",
    );
    let out = run(frond().args(["map", "--rig"]).arg(&f.rig), hand);
    assert_eq!(out.status.code(), Some(1));
    let ts: Vec<f64> = poses(&out.stdout).iter().map(|p| p.t).collect();
    assert_eq!(ts, [0.0, 0.2, 0.5]);
    let err = text(&out.stderr);
    let lines: Vec<&str> = err.lines().collect();
    assert!(lines[0].starts_with("line 2: ") && lines[0].contains("wrist"), "{err}");
    assert!(lines[1].starts_with("line 4: ") && lines[1].contains("thumb[1]"), "{err}");
    assert!(lines[2].starts_with("line 5: ") && lines[2].contains("thumb"), "{err}");
    assert!(lines[3].starts_with("frond: error: 3 of 6 input lines were malformed"), "{err}");
}

#[test]
fn map_names_a_missing_or_invalid_rig_file() {
    let f = files();
    let missing = f.root.join("nope.toml");
    let out = run(frond().args(["map", "--rig"]).arg(&missing), "");
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.starts_with(&format!("frond: error: cannot read rig {}: ", path_str(&missing)))
            && err.matches("No such file").count() == 1,
        "{err}"
    );

    let bad = f.root.join("bad.toml");
    std::fs::write(&bad, RIG.replace("tau = 1", "tau = 7")).unwrap();
    let out = run(frond().args(["map", "--rig"]).arg(&bad), "");
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains(&path_str(&bad)) && err.contains("tau"), "{err}");

    let bad_cal = f.root.join("badcal.toml");
    std::fs::write(&bad_cal, CALIBRATION.replace("[40.0, 20.0, 16.0]", "[40.0, -1.0, 16.0]")).unwrap();
    let out = run(frond().args(["map", "--rig"]).arg(&f.rig).arg("--calibration").arg(&bad_cal), "");
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains(&path_str(&bad_cal)) && err.contains("thumb_range_deg[1]"), "{err}");
}

fn path_str(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn usage_errors_exit_2_with_the_frond_prefix() {
    let f = files();
    let cases: Vec<Vec<String>> = vec![
        vec!["map".into()],
        vec!["tap".into(), "--count".into(), "many".into()],
        vec!["frobnicate".into()],
        vec!["record".into(), "start".into(), "../escape".into()],
        vec!["filter".into(), "butterworth".into()],
        vec![
            "map".into(),
            "--filter".into(),
            "lowpass:cutoff_hz=-3".into(),
            "--rig".into(),
            path_str(&f.rig),
        ],
        vec!["demo".into(), "--seconds".into(), "-1".into()],
        vec!["calibrate".into(), "--user".into(), "a/b".into(), "--yes".into()],
        vec!["mark".into(), "x".repeat(300)],
    ];
    for args in cases {
        let out = run(frond().args(&args).arg("--socket-dir").arg(f.root.join("nowhere")), "");
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.starts_with("frond: error: "), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn help_exits_0() {
    let out = run(frond().arg("--help"), "");
    assert!(out.status.success());
    let help = text(&out.stdout);
    for cmd in ["status", "tap", "map", "calibrate", "record", "take", "demo", "--socket-dir", "--takes-dir"]
    {
        assert!(help.contains(cmd), "{cmd} missing from\n{help}");
    }
}

#[test]
fn commands_without_a_daemon_say_how_to_start_it() {
    let f = files();
    let dir = f.root.join("sockets");
    for args in [&["status"][..], &["tap", "--count", "1"], &["record", "stop"], &["mark", "hello"]] {
        let out = run(frond().args(args).arg("--socket-dir").arg(&dir), "");
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = text(&out.stderr);
        assert!(err.contains("the frond daemon is not running"), "{args:?}: {err}");
        assert!(err.contains(&path_str(&dir)), "{args:?}: {err}");
        assert!(err.contains("frondd --socket-dir"), "{args:?}: {err}");
    }
    // The environment variable works like the flag.
    let out = run(frond().arg("status").env("FROND_SOCKET_DIR", &dir), "");
    assert!(text(&out.stderr).contains(&path_str(&dir.join("control.sock"))), "{}", text(&out.stderr));
}

/// `frond take field --compact` leaves the plants out, and the file reads back (as the daemon,
/// `take export --field` and frond-gltf read it) with the same plants as the full file.
#[test]
fn a_compact_field_file_reads_back_with_the_plants_of_the_full_one() {
    use frond_formats::field_json::FieldJson;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::common::performed(d);
    let field = |extra: &[&str], out: &str| {
        let o = crate::common::frond(d)
            .args(["take", "field", "wave", "--rows", "30", "--cols", "40", "--cell", "0.2"])
            .args(["--speed", "1.5", "--direction", "30", "--seed", "7", "-o", out])
            .args(extra)
            .output()
            .unwrap();
        crate::common::ok(&o)
    };
    let said = field(&[], "full.json");
    assert!(said.contains("(1200 plants)"), "{said}");
    let said = field(&["--compact"], "compact.json");
    assert!(said.contains("(1200 plants, left out: readers make them from the parameters)"), "{said}");
    let (full, compact) = (
        std::fs::read_to_string(d.join("full.json")).unwrap(),
        std::fs::read_to_string(d.join("compact.json")).unwrap(),
    );
    let raw: serde_json::Value = serde_json::from_str(&compact).unwrap();
    assert_eq!(raw["plants"].as_array().map_or(0, Vec::len), 0, "no plants written");
    assert!(compact.len() * 50 < full.len(), "{} bytes against {}", compact.len(), full.len());
    let (full, compact) = (
        frond_motion::field::Field::from_json(&full).unwrap(),
        frond_motion::field::Field::from_json(&compact).unwrap(),
    );
    assert_eq!(compact.plants.len(), 1200);
    assert_eq!(compact, full, "the plants made from the parameters are the ones written out");
}
