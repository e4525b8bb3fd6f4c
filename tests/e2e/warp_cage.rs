//! `frond-warp serve --mode cage` on a real daemon (issue 17): the live hand bends the picture's
//! plant through its skinned crown cage (seed 000 Eq. 1 on the seed-004 cage tree), and when
//! the daemon stops the page falls back to the rest shape, the still picture exactly.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::Duration;

use frond_e2e::{Daemon, Proc, bin, repo_root, wait_for};
use serde_json::Value;

/// `GET path` from `addr` (HTTP/1.1, `Connection: close`): status and body.
fn get(addr: &str, path: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).expect("connect to frond-warp");
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let end = raw.windows(4).position(|w| w == b"\r\n\r\n").expect("HTTP head") + 4;
    let head = String::from_utf8_lossy(&raw[..end]).to_string();
    let status = head.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    (status, raw[end..].to_vec())
}

fn json(addr: &str, path: &str) -> Value {
    let (status, body) = get(addr, path);
    assert_eq!(status, 200, "GET {path}");
    serde_json::from_slice(&body).expect("JSON")
}

/// Shoelace area of a closed polygon given as JSON `[[x, y], ...]`.
fn area(vertices: &Value) -> f64 {
    let p: Vec<(f64, f64)> = vertices
        .as_array()
        .unwrap()
        .iter()
        .map(|v| (v[0].as_f64().unwrap(), v[1].as_f64().unwrap()))
        .collect();
    (0..p.len()).map(|i| p[i].0 * p[(i + 1) % p.len()].1 - p[(i + 1) % p.len()].0 * p[i].1).sum::<f64>().abs()
        / 2.0
}

#[test]
fn the_live_hand_bends_the_cage_preview_and_rest_returns_when_the_daemon_stops() {
    let dir = tempfile::tempdir().unwrap();
    let mut daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "shrub"]);
    let images = repo_root().join("rig-files/images");
    let child = Command::new(bin("frond-warp"))
        .args(["serve", "--mode", "cage", "--listen", "127.0.0.1:0", "--image"])
        .arg(images.join("shrub-background.png"))
        .arg("--layer")
        .arg(images.join("shrub.png"))
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond-warp serve --mode cage");
    let mut warp = Proc { child, name: "frond-warp".into() };
    let mut line = String::new();
    BufReader::new(warp.child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let addr =
        line.trim().strip_prefix("listening on http://").expect("the URL").trim_end_matches('/').to_string();

    // The hand drives, on the daemon's own rig.
    assert!(
        wait_for(Duration::from_secs(20), || json(&addr, "/status")["drive"] == "hand"),
        "the hand never drove the picture: {}",
        json(&addr, "/status")
    );
    let status = json(&addr, "/status");
    assert_eq!(status["rig"], "rig shrub (the daemon's)", "{status}");
    assert_eq!(status["daemon"]["connected"], true, "{status}");

    // The crown cage moves with the hand, its shape kept (skinning rotates, it does not squash),
    // and the picture moves with it.
    let crown = json(&addr, "/cages")["crown"].clone();
    let crown_of =
        |cages: &Value| cages["cages"].as_array().unwrap().iter().find(|c| c["id"] == crown).unwrap().clone();
    let (_, still) = get(&addr, "/still");
    let rest_area = {
        let tree = Command::new(bin("frond-warp"))
            .args(["cage", "build", "--layer"])
            .arg(images.join("shrub.png"))
            .arg("-o")
            .arg(dir.path().join("cage.json"))
            .output()
            .unwrap();
        assert!(tree.status.success(), "{}", String::from_utf8_lossy(&tree.stderr));
        let file: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("cage.json")).unwrap()).unwrap();
        let c = file["cages"].as_array().unwrap().iter().find(|c| c["id"] == crown).unwrap().clone();
        area(&c["vertices"])
    };
    let (mut moved_px, mut frames) = (0.0f64, Vec::new());
    for _ in 0..20 {
        let now = crown_of(&json(&addr, "/cages"));
        let a = area(&now["vertices"]);
        assert!((a / rest_area - 1.0).abs() < 0.15, "crown area {a} against {rest_area} at rest");
        let (_, f) = get(&addr, "/frame");
        let diff = f.iter().zip(&still).filter(|(a, b)| a.abs_diff(**b) > 30).count();
        moved_px = moved_px.max(diff as f64);
        frames.push(f);
        std::thread::sleep(Duration::from_millis(100));
    }
    eprintln!("the hand moved up to {moved_px} channel values by more than 30");
    assert!(moved_px > 500.0, "the hand moved at most {moved_px} channel values of the picture");
    assert!(frames.windows(2).any(|w| w[0] != w[1]), "the picture never changed with the hand");

    // The daemon stops: no fresh poses, so the plant returns to rest, the still picture exactly.
    daemon.proc.terminate(Duration::from_secs(10));
    assert!(
        wait_for(Duration::from_secs(10), || json(&addr, "/status")["drive"] == "rest"),
        "{}",
        json(&addr, "/status")
    );
    assert!(
        wait_for(Duration::from_secs(5), || get(&addr, "/frame").1 == still),
        "rest is not the still picture"
    );
    warp.terminate(Duration::from_secs(5));
}
