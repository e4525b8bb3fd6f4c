//! Issue 14, point 11: one set of plausibility limits for hand samples, calibrations and rigs,
//! applied alike by the live daemon and by the offline commands. A wrist of 400 degrees or 1e30
//! is dropped by the OSC source and refused by `frond map`, line for line; a calibration with a
//! thumb range of 1e-45 degrees or a neutral of 1e30 degrees, and a rig scaling a joint by 1e30,
//! are refused by `frondd` and by `frond map` with the same paths.

use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::time::Duration;

use frond_e2e::{Daemon, bin, fresh_poses, frond_map, repo_root, send_osc_pitches, wait_for};
use frond_sdk::Subscriber;

#[test]
fn the_hand_limits_are_the_same_live_and_offline() {
    let dir = tempfile::tempdir().unwrap();
    let port = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let rig = repo_root().join("rig-files/plants/grass.toml");
    let source = format!("osc://127.0.0.1:{port}");
    let daemon =
        Daemon::start(dir.path(), &["--source", &source, "--rig", rig.to_str().unwrap(), "--filter", "none"]);
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    // Wrist pitch per sample: the limit itself is allowed on both sides, 400 and 1e30 are not.
    let pitches = [10.0f32, 400.0, 1e30, -360.0, 360.0, 20.0];
    let samples: Vec<(f64, f32)> = pitches.iter().enumerate().map(|(k, &p)| (k as f64 * 0.01, p)).collect();
    send_osc_pitches(port, &samples, Duration::from_millis(10));
    let fresh = fresh_poses(&mut sub, 4, Duration::from_secs(10));
    assert_eq!(fresh.len(), 4, "the four plausible samples are published");
    wait_for(Duration::from_secs(2), || daemon.status().source.rejected == 2);

    let jsonl: String = pitches
        .iter()
        .enumerate()
        .map(|(k, p)| format!("{{\"t\":{},\"wrist\":[{p},0,0],\"thumb\":[0,0,0]}}\n", k as f64 * 0.01))
        .collect();
    let out = frond_map(&["--filter", "none", "--rig", rig.to_str().unwrap()], &jsonl);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("line 2: `wrist[0]`: 400 degrees is not a hand angle (finite, within ±360)"),
        "{err}"
    );
    assert!(err.contains("line 3: `wrist[0]`: 1000000000000000000000000000000 degrees"), "{err}");
    let lines: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 4, "the same four lines are mapped offline");
    for (line, pose) in lines.iter().zip(&fresh) {
        for (j, joint) in pose.joints_deg.iter().enumerate() {
            let offline = line["joints"][j][0].as_f64().unwrap();
            assert!((offline - f64::from(joint[0])).abs() < 1e-3, "{line} vs {pose:?}");
        }
    }
    // The root follows Eq. 2 with the grass rig's s_pitch(0) = 1: the limit maps through.
    assert_eq!(lines[1]["joints"][0][0].as_f64(), Some(-360.0));
}

#[test]
fn implausible_calibrations_and_rigs_are_refused_by_the_daemon_and_offline_alike() {
    let dir = tempfile::tempdir().unwrap();
    let calibration = dir.path().join("tiny.toml");
    std::fs::write(
        &calibration,
        "id = \"tiny\"\nneutral_wrist_deg = [1e30, 0.0, 0.0]\nneutral_thumb_deg = [0.0, 0.0, 0.0]\n\
         thumb_range_deg = [1e-45, 60.0, 60.0]\n",
    )
    .unwrap();
    let grass = std::fs::read_to_string(repo_root().join("rig-files/plants/grass.toml")).unwrap();
    assert!(grass.contains("s_pitch = 1.0"), "the grass rig's root scale is where this test expects it");
    let rig = dir.path().join("wild.toml");
    std::fs::write(&rig, grass.replacen("s_pitch = 1.0", "s_pitch = 1e30", 1)).unwrap();

    let cases: [(&str, &std::path::Path, &[&str]); 2] = [
        (
            "--calibration",
            &calibration,
            &[
                "neutral_wrist_deg[0]: a hand angle (degrees) must be between -360 and 360, found 1000000000000000000000000000000",
                "thumb_range_deg[0]: a thumb range (degrees) must be between 1 and 360, found 0.000000000000000000000000000000000000000000001",
            ],
        ),
        (
            "--rig",
            &rig,
            &[
                "joints[0].s_pitch: a joint scale must be between -20 and 20, found 1000000000000000000000000000000",
            ],
        ),
    ];
    for (flag, path, problems) in cases {
        let frondd = Command::new(bin("frondd"))
            .arg("--socket-dir")
            .arg(dir.path().join("run"))
            .arg("--takes-dir")
            .arg(dir.path().join("takes"))
            .args(["--source", "in-process", flag])
            .arg(path)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let grass = repo_root().join("rig-files/plants/grass.toml");
        let offline = if flag == "--rig" {
            frond_map(&[flag, path.to_str().unwrap()], "")
        } else {
            frond_map(&["--rig", grass.to_str().unwrap(), flag, path.to_str().unwrap()], "")
        };
        for (who, out) in [("frondd", &frondd), ("frond map", &offline)] {
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{who} {flag} accepted {}", path.display());
            assert!(err.contains(&path.display().to_string()), "{who}: {err}");
            for problem in problems {
                assert!(err.contains(problem), "{who} {flag}: {err}");
            }
        }
    }
}
