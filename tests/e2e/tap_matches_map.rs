//! The foundation's acceptance test: the virtual glove plays a known hand file through a FUSE
//! hidraw node, `frondd` opens it through hidapi (the same code path as a physical glove), and
//! `frond tap` must receive, in order and with no sequence gap, one fresh frame per input sample,
//! equal to the pose `frond map` computes offline from the same file (filter none). Once with the
//! grass and no calibration, once with the shrub (which declares `bend_range_deg`) and a
//! calibration with measured wrist ranges, so the wrist calibration of seed 000, section 5.4 is
//! the same live and offline.

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use frond_e2e::{Daemon, bin, fuse_available, repo_root, start_vhid};
use serde_json::Value;

/// A hand performance with values on the glove's 0.01 degree grid (what the report can carry).
fn hand_file(samples: usize, rate_hz: f64) -> String {
    let mut out = String::new();
    for k in 0..samples {
        let t = k as f64 / rate_hz;
        let q = |v: f64| (v * 100.0).round() / 100.0;
        let wrist = [q(25.0 * (1.3 * t).sin()), q(-18.0 * (0.7 * t + 0.4).sin()), q(40.0 * (0.5 * t).sin())];
        let thumb = [q(30.0 + 20.0 * (2.0 * t).sin()), q(-12.5 + 35.0 * (1.1 * t).cos()), q(10.0 * t)];
        out.push_str(&format!(
            "{{\"t\":{t},\"wrist\":[{},{},{}],\"thumb\":[{},{},{}]}}\n",
            wrist[0], wrist[1], wrist[2], thumb[0], thumb[1], thumb[2]
        ));
    }
    out
}

fn joints_of(v: &Value) -> Vec<u32> {
    v["joints"]
        .as_array()
        .expect("joints array")
        .iter()
        .flat_map(|j| {
            j.as_array().expect("joint").iter().map(|x| (x.as_f64().expect("number") as f32).to_bits())
        })
        .collect()
}

#[test]
fn tap_receives_every_sample_as_frond_map_computes_it() {
    tap_matches_map("grass", None);
}

#[test]
fn tap_matches_map_with_a_wrist_calibration_mapped_onto_the_shrub_bend_range() {
    tap_matches_map("shrub", Some("example-user"));
}

fn tap_matches_map(rig: &str, calibration: Option<&str>) {
    if !fuse_available() {
        eprintln!("skipped: /dev/fuse is missing, so the virtual glove cannot present a hidraw node");
        return;
    }
    const SAMPLES: usize = 300;
    let dir = tempfile::tempdir().unwrap();
    let hand_path = dir.path().join("hand.jsonl");
    std::fs::write(&hand_path, hand_file(SAMPLES, 100.0)).unwrap();
    let rig = repo_root().join(format!("rig-files/plants/{rig}.toml"));
    let cal_args: Vec<String> = calibration
        .map(|c| {
            let path = repo_root().join(format!("rig-files/calibrations/{c}.toml"));
            vec!["--calibration".to_string(), path.to_str().unwrap().to_string()]
        })
        .unwrap_or_default();

    // Offline: the expected poses.
    let map = Command::new(bin("frond"))
        .args(["map", "--rig"])
        .arg(&rig)
        .args(["--filter", "none"])
        .args(&cal_args)
        .stdin(std::fs::File::open(&hand_path).unwrap())
        .output()
        .expect("run frond map");
    assert!(map.status.success(), "frond map failed: {}", String::from_utf8_lossy(&map.stderr));
    let expected: Vec<Value> =
        String::from_utf8(map.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(expected.len(), SAMPLES);

    // Live: glove node -> frondd (hidapi by path) -> frond tap.
    let node = dir.path().join("vhid").join("hidraw-e2e");
    let (_vhid, node_path, _vhid_out) = start_vhid(&[
        "--play",
        hand_path.to_str().unwrap(),
        "--node",
        node.to_str().unwrap(),
        "--start-delay-ms",
        "2500",
        "--linger-ms",
        "3000",
    ]);
    let mut daemon_args = vec!["--device", node_path.to_str().unwrap(), "--rig", rig.to_str().unwrap()];
    daemon_args.extend(["--filter", "none"]);
    daemon_args.extend(cal_args.iter().map(String::as_str));
    let daemon = Daemon::start(dir.path(), &daemon_args);
    let status = daemon.status();
    assert_eq!(status.source.kind, "fuse-hidraw", "{status:?}");
    let mut tap = daemon
        .frond()
        .args(["tap", "--jsonl", "--include-held"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond tap");
    let reader = BufReader::new(tap.stdout.take().unwrap());
    let mut fresh = Vec::new();
    let mut last_seq: Option<u64> = None;
    let deadline = Instant::now() + Duration::from_secs(40);
    for line in reader.lines() {
        let line = line.expect("tap output");
        let v: Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("tap printed {line:?}: {e}"));
        let seq = v["seq"].as_u64().expect("seq");
        if let Some(prev) = last_seq {
            assert_eq!(seq, prev + 1, "sequence gap or reordering in tap output");
        }
        last_seq = Some(seq);
        let held = v["flags"].as_array().is_some_and(|f| f.iter().any(|x| x == "held"));
        if !held {
            fresh.push(v);
        }
        if fresh.len() == SAMPLES || Instant::now() > deadline {
            break;
        }
    }
    let _ = tap.kill();
    let _ = tap.wait();
    assert_eq!(fresh.len(), SAMPLES, "tap saw {} fresh frames of {SAMPLES}", fresh.len());
    for (i, (got, want)) in fresh.iter().zip(&expected).enumerate() {
        assert_eq!(joints_of(got), joints_of(want), "frame {i}: live {got} != offline {want}");
        let (tg, tw) = (got["t"].as_f64().unwrap(), want["t"].as_f64().unwrap());
        assert!((tg - tw).abs() <= 1e-6, "frame {i}: device time {tg} != file time {tw}");
    }
    let status = daemon.status();
    assert_eq!(status.source.rejected, 0, "{status:?}");
    assert_eq!(status.source.device_seq_gaps, 0, "{status:?}");
    let _ = std::io::stderr().flush();
}
