//! Timecode (issue 18): a take the daemon records knows when it was recorded on the host's wall
//! clock, so its USD and glTF exports carry the SMPTE timecode of their first frame (UTC time of
//! day at the export's rate), which lines them up with reference video and audio; a given start
//! replaces it.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use frond_e2e::Daemon;

fn tc_frames(tc: &str, rate: u64) -> u64 {
    let p: Vec<u64> = tc.split(':').map(|x| x.parse().unwrap()).collect();
    ((p[0] * 60 + p[1]) * 60 + p[2]) * rate + p[3]
}

#[test]
fn recorded_takes_carry_the_timecode_of_their_first_frame() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    let before = SystemTime::now().duration_since(UNIX_EPOCH).unwrap();
    daemon.frond_ok(&["record", "start", "clocked"]);
    std::thread::sleep(Duration::from_millis(600));
    daemon.frond_ok(&["record", "stop"]);
    let after = SystemTime::now().duration_since(UNIX_EPOCH).unwrap();
    let usda = dir.path().join("clocked.usda");
    daemon.frond_ok(&["take", "export", "clocked", "--usd", "-o", usda.to_str().unwrap()]);
    let text = std::fs::read_to_string(&usda).unwrap();
    let tc = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("string timecode_start = \""))
        .and_then(|l| l.strip_suffix('"'))
        .unwrap_or_else(|| panic!("no timecode_start in {}", &text[..400]));
    assert!(text.contains("string timecode_rate = \"30\""));
    // The first frame came between `before` and `after` (UTC time of day, in frames of 30 fps).
    let of_day = |d: Duration| (d.as_secs() % 86_400) * 30 + u64::from(d.subsec_nanos()) * 30 / 1_000_000_000;
    let (lo, hi, got) = (of_day(before), of_day(after), tc_frames(tc, 30));
    let within = if lo <= hi { lo <= got && got <= hi } else { got >= lo || got <= hi }; // midnight
    assert!(within, "timecode {tc} ({got}) outside [{lo}, {hi}] frames of the day");
    // frond-gltf bakes the same start into the asset's extras (same rate: 30 keys a second).
    let glb = dir.path().join("clocked.glb");
    let take = daemon.takes_dir.join("clocked.take");
    let out = std::process::Command::new(frond_e2e::bin("frond-gltf"))
        .args(["bake", "-q", "--rig", "grass", "--take"])
        .arg(&take)
        .arg("-o")
        .arg(&glb)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(&glb).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    assert_eq!(doc["asset"]["extras"]["timecode_start"], tc, "{}", doc["asset"]["extras"]);
    // The JSON Lines export counts the same timecode up, one frame a line.
    let lines = daemon.frond_ok(&["take", "export", "clocked", "--fps", "30", "--timecode"]);
    let tcs: Vec<String> = lines
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["tc"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(tcs[0], tc);
    let day = 86_400 * 30;
    assert!(
        tcs.windows(2).all(|w| (tc_frames(&w[1], 30) + day - tc_frames(&w[0], 30)) % day == 1),
        "{tcs:?}"
    );
    // A given start wins; a bad one is a usage error.
    daemon.frond_ok(&[
        "take",
        "export",
        "clocked",
        "--usd",
        "-o",
        usda.to_str().unwrap(),
        "--timecode-start",
        "01:00:00:00",
    ]);
    assert!(std::fs::read_to_string(&usda).unwrap().contains("string timecode_start = \"01:00:00:00\""));
    let out = daemon
        .frond()
        .args([
            "take",
            "export",
            "clocked",
            "--usd",
            "-o",
            usda.to_str().unwrap(),
            "--timecode-start",
            "01:00:00:30",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("frames 30 is out of range"));
}
