//! The 3D view on a real daemon: the live plant, its layers and a field's plants against
//! forward kinematics; recording, takes, stage controls and the warp panel from the page.

use std::time::Duration;

use frond_e2e::{Daemon, wait_for};
use frond_protocol::{ElementId, ElementKind};
use frond_webdriver::{browser, poll, start_session};
use serde_json::{Value, json};

use super::kinematics::{Frame, chain, check_bones, heights, joints_of, model};
use super::{request, request_json, save_screenshot, start_console};

#[test]
fn the_page_shows_the_live_plant_and_records_a_take() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1200,760", &url);
    let h = heights(&d);
    assert!((h[3] - 0.24).abs() < 1e-6, "the grass rig's top joint: {h:?}");
    let grass = model("grass");
    // Three snapshots: each matches its pose; the sway moves the plant between them.
    let first = check_bones(&d, 0, &grass);
    std::thread::sleep(Duration::from_millis(400));
    check_bones(&d, 0, &grass);
    std::thread::sleep(Duration::from_millis(400));
    let third = check_bones(&d, 0, &grass);
    assert_ne!(first, third, "the virtual glove sways: the poses differ");
    // The warp preview: the hand drives its wind (the readout says so), and the grass visibly
    // moves (more than 4 % of the pixels by more than 30 levels within 3 s; the old preview
    // moved 574 of 76,800, 0.75 %), at well under the old preview's 7 MB/s.
    let warp_state = poll("the warp panel driven by the hand", Duration::from_secs(15), || {
        let v = d.script("return window.frondConsole.state.warp.state;");
        (v["source"] == "hand").then_some(v)
    });
    assert!(warp_state["wind"]["strength"].as_f64().is_some(), "{warp_state}");
    let readout = poll("the wind readout", Duration::from_secs(5), || {
        let t = d.script("return document.getElementById('warp-state').textContent;");
        t.as_str().filter(|s| s.starts_with("wind from the hand")).map(str::to_string)
    });
    assert!(readout.contains("strength"), "{readout}");
    d.script("return window.frondConsole.warpGrab();");
    std::thread::sleep(Duration::from_secs(3));
    let moved = d.script("return window.frondConsole.warpDiff();");
    let (changed, pixels) = (moved["changed"].as_u64().unwrap(), moved["pixels"].as_u64().unwrap());
    assert!(changed * 25 > pixels, "only {changed} of {pixels} pixels moved visibly: {moved}");
    // Each frame is one JPEG: at 30 FPS under 1.2 MB/s (raw RGBA was 9.2 MB/s at 30 FPS).
    let per_frame = moved["bytes"].as_f64().unwrap() / moved["frames"].as_f64().unwrap();
    assert!(per_frame < 40_000.0, "{per_frame} bytes a frame");
    // The health panel names the source and the rate.
    let source = poll("the health panel", Duration::from_secs(10), || {
        let t = d.script("return document.getElementById('source').textContent;");
        t.as_str().filter(|s| s.contains("connected")).map(str::to_string)
    });
    assert!(source.contains("in-process"), "{source}");
    // The delivery latency, measured by the console on every pose, with its histogram.
    let delivery = poll("the delivery latency", Duration::from_secs(10), || {
        let t = d.script("return document.getElementById('delivery').textContent;");
        t.as_str().filter(|s| s.starts_with("daemon → console p50")).map(str::to_string)
    });
    assert!(delivery.contains("p99"), "{delivery}");
    // The in-process glove keeps its own clock (from 0 at start): the page says glove-to-console
    // latency cannot be measured (the FUSE glove with the host's clock is measured in
    // calibration.rs).
    let shown = poll("the glove latency line", Duration::from_secs(10), || {
        let t = d.script("return document.getElementById('glove-latency').textContent;");
        t.as_str().filter(|s| s.starts_with("the glove keeps its own clock")).map(str::to_string)
    });
    assert!(shown.contains("cannot be measured"), "{shown}");
    // The daemon's lateness histogram since start, as the page got it: every tick in a bucket
    // (one status report, read in one go; the daemon reads its count and its buckets a moment
    // apart while the loop runs).
    let daemon_status = d.script("return window.frondConsole.state.status.daemon;");
    let hist = &daemon_status["lateness_histogram"];
    let counted: u64 = hist.as_array().unwrap().iter().map(|b| b["count"].as_u64().unwrap()).sum();
    let samples = daemon_status["lateness"]["samples"].as_u64().unwrap();
    let close = counted.abs_diff(samples) <= samples / 100 + 10;
    assert!(counted > 100 && close, "{counted} in the histogram, {samples} samples");
    // Record from the page, then stop: the take is on disk with the frames the daemon counted.
    d.script(
        "document.getElementById('take-name').value = 'console_take';
         document.getElementById('record-start').click();",
    );
    assert!(wait_for(Duration::from_secs(10), || daemon.status().recording.is_some_and(|r| r.active)));
    std::thread::sleep(Duration::from_millis(300));
    d.script("document.getElementById('record-stop').click();");
    let said = poll("the stop result", Duration::from_secs(10), || {
        let t = d.script("return document.getElementById('control-result').textContent;");
        t.as_str().filter(|s| s.starts_with("stopped")).map(str::to_string)
    });
    let frames: u64 = said.split_whitespace().nth(2).and_then(|n| n.parse().ok()).expect(&said);
    let take = daemon.takes_dir.join("console_take.take");
    let bytes = std::fs::read(&take).expect("the take file");
    let scan = frond_formats::scan_take(&bytes).expect("a sound take");
    assert!(scan.ended, "the take is closed");
    assert_eq!(scan.frames.len() as u64, frames, "{said}");
    assert!(frames > 100, "0.3 s at 1 kHz: {said}");
    // The takes panel lists it with that frame count; playing it shows the take's poses.
    let row = poll("the take in the list", Duration::from_secs(10), || {
        let v = d.script(
            "const tr = document.querySelector('#take-list tr[data-take=\"console_take\"]');
             return tr ? [...tr.children].map(td => td.textContent) : null;",
        );
        (!v.is_null()).then_some(v)
    });
    assert_eq!(row[1].as_str().unwrap(), frames.to_string(), "{row}");
    assert_eq!(row[3], "complete", "{row}");
    d.script("document.querySelector('#take-list tr[data-take=\"console_take\"] .take-play').click();");
    let main: Vec<_> = scan.frames.iter().filter(|f| f.element.is_global()).map(|f| f.pose).collect();
    for _ in 0..3 {
        let snap = poll("the take playing", Duration::from_secs(10), || {
            let v = d.script("return window.frondConsole.snapshot(0);");
            (v["pose"]["take"] == "console_take").then_some(v)
        });
        // Frame k of the playback is the take at k / 60 s from its first pose: the recorded
        // poses bracketing that time (1 ms apart) agree with it within their own change.
        let k = snap["pose"]["k"].as_u64().unwrap() as f64;
        let t = main[0].t + k / 60.0;
        let j = joints_of(&snap["pose"]["j"]);
        let after = main.iter().position(|p| p.t >= t - 1e-9).unwrap_or(main.len() - 1);
        let before = after.saturating_sub(1);
        for (i, joint) in j.iter().enumerate() {
            for (a, &got) in joint.iter().enumerate() {
                let (lo, hi) = (main[before].joints_deg[i][a], main[after].joints_deg[i][a]);
                let (lo, hi) = (lo.min(hi) - 1e-3, lo.max(hi) + 1e-3);
                assert!((lo..=hi).contains(&got), "frame {k} joint {i}.{a}: {got} not within [{lo}, {hi}]");
            }
        }
        check_bones(&d, 0, &grass);
        std::thread::sleep(Duration::from_millis(150));
    }
    // Downloads: the GLB frond-gltf bakes (its animation named after the take) and the JSONL.
    let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
    let host = format!("Host: {addr}\r\n");
    let (s, head, _) = request(&addr, "GET", "/api/takes/console_take.glb", &host, "");
    assert_eq!(s, 200);
    assert!(head.contains("filename=\"console_take.glb\""), "{head}");
    let (s, _, body) = request(&addr, "GET", "/api/takes/console_take.jsonl", &host, "");
    assert_eq!(s, 200);
    let held = scan
        .frames
        .iter()
        .filter(|f| f.element.is_global() && f.flags & frond_protocol::PoseFlags::HELD.0 != 0)
        .count();
    assert_eq!(body.lines().count(), main.len() - held, "one line per pose, held ones left out");
    d.script("document.getElementById('player-live').click();");
    // The picture (WebGL on SwiftShader): two times differ where the plant is, and only there.
    let webgl = d.script("return window.frondConsole.state.webgl;");
    assert_eq!(webgl, json!(true), "the headless browser gives WebGL (SwiftShader)");
    d.script("return window.frondConsole.grab();");
    let diff = poll("the plant to move on screen", Duration::from_secs(10), || {
        let v = d.script("return window.frondConsole.diffSinceGrab();");
        (v["inside"].as_u64().unwrap() > 200).then_some(v)
    });
    let (inside, outside) = (diff["inside"].as_u64().unwrap(), diff["outside"].as_u64().unwrap());
    assert!(outside * 4 < inside, "changes outside the plant's box: {diff}");
    save_screenshot(&d, "screenshot.png");
    // Stage controls: the filter and the rig, set from the page, are the daemon's; the view
    // follows the new rig (the flower's bones against its own forward kinematics).
    d.script(
        "document.getElementById('filter-spec').value = 'lowpass';
         document.querySelector('#filter-form button').click();",
    );
    let ok = wait_for(Duration::from_secs(10), || daemon.status().filter.starts_with("lowpass"));
    assert!(
        ok,
        "filter not set: {} ({})",
        daemon.status().filter,
        d.script("return document.getElementById('control-result').textContent;")
    );
    d.script(
        "document.getElementById('rig-select').value = 'flower';
         document.querySelector('#rig-form button').click();",
    );
    assert!(wait_for(Duration::from_secs(10), || daemon.status().rig_name == "flower"), "rig not set");
    poll("the view to show the flower", Duration::from_secs(20), || {
        (d.script("return window.frondConsole.state.map && window.frondConsole.state.map.rig;") == "flower")
            .then_some(())
    });
    check_bones(&d, 0, &model("flower"));
}

#[test]
fn the_flower_and_its_leaf_layer_follow_their_two_hands() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(
        dir.path(),
        &["--rig", "flower", "--hand", "main=in-process", "--hand", "leaf=in-process,element=leaf"],
    );
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1000,700", &url);
    let flower = model("flower");
    assert_eq!(flower.elements.iter().filter(|e| e.element == 0).count(), 2, "the flower has two leaves");
    for _ in 0..3 {
        check_bones(&d, 0, &flower);
        check_bones(&d, 1, &flower);
        std::thread::sleep(Duration::from_millis(300));
    }
}

#[test]
fn a_field_started_from_the_page_stands_its_plants_where_the_field_puts_them() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    // A take to play: two seconds of the glove.
    daemon.frond_ok(&["record", "start", "sway"]);
    std::thread::sleep(Duration::from_millis(2000));
    daemon.frond_ok(&["record", "stop"]);
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1000,700", &url);
    poll("the take in the list", Duration::from_secs(10), || {
        let v = d.script("return !!document.querySelector('#take-list tr[data-take=\"sway\"] .take-field');");
        (v == json!(true)).then_some(())
    });
    d.script("document.querySelector('#take-list tr[data-take=\"sway\"] .take-field').click();");
    // The daemon plays the field: 16 field-plant elements announced.
    let ids = poll("the field's plants in the element table", Duration::from_secs(10), || {
        let ids: Vec<ElementId> = daemon
            .status()
            .elements
            .iter()
            .filter(|e| e.kind == ElementKind::FieldPlant)
            .map(|e| e.id)
            .collect();
        (ids.len() == 16).then_some(ids)
    });
    // The field as the console laid it out, and as `frond take field` would (same parameters).
    let field: Value = serde_json::from_str(&request_json(&url, "/api/field")).unwrap();
    assert_eq!(field["take"], "sway");
    let grass = model("grass");
    for &id in ids.iter().step_by(5) {
        let snap = poll(&format!("field plant {id} in the view"), Duration::from_secs(20), || {
            let v = d.script(&format!("return window.frondConsole.snapshot({id});"));
            (!v.is_null() && !v["placement"].is_null()).then_some(v)
        });
        let i = snap["placement"]["index"].as_u64().unwrap() as usize;
        let at = &field["positions_m"][i];
        let scale = field["scales"][i].as_f64().unwrap();
        assert_eq!(snap["placement"]["position"], *at, "plant {i} stands where the field puts it");
        let (x, z) = (at[0].as_f64().unwrap(), at[1].as_f64().unwrap());
        let frames = chain(Frame::IDENTITY, &grass.skeleton.heights_m, &joints_of(&snap["pose"]["j"]));
        let bones = &snap["bones"][0];
        for (j, f) in frames.iter().enumerate() {
            let want = [x + scale * f.pos[0], scale * f.pos[1], z + scale * f.pos[2]];
            for k in 0..3 {
                let got = bones[j][k].as_f64().unwrap();
                assert!(
                    (got - want[k]).abs() <= 1e-4 * 0.24,
                    "plant {i} joint {j} axis {k}: page {got}, want {}",
                    want[k]
                );
            }
        }
    }
}

#[test]
fn a_torn_take_is_listed_torn_and_repaired_from_the_page() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    daemon.frond_ok(&["record", "start", "cut"]);
    std::thread::sleep(Duration::from_millis(500));
    daemon.frond_ok(&["record", "stop"]);
    // A crash mid-record: the End record gone and half a record after the last frame.
    let path = daemon.takes_dir.join("cut.take");
    let bytes = std::fs::read(&path).unwrap();
    let sound = frond_formats::scan_take(&bytes).unwrap();
    let end = sound.valid_len as usize - frond_formats::take::RECORD_HEAD_LEN - 9;
    let mut torn = bytes[..end].to_vec();
    torn.extend_from_slice(&bytes[end - 20..end - 3]);
    std::fs::write(&path, &torn).unwrap();
    // Old enough not to look like a recording in progress.
    let old = std::time::SystemTime::now() - Duration::from_secs(60);
    std::fs::File::options().write(true).open(&path).unwrap().set_modified(old).unwrap();
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1000,800", &url);
    let row = |d: &frond_webdriver::Driver| {
        d.script(
            "const tr = document.querySelector('#take-list tr[data-take=\"cut\"]');
             return tr ? [...tr.children].map(td => td.textContent) : null;",
        )
    };
    poll("the torn take", Duration::from_secs(10), || (row(&d)[3] == "torn").then_some(()));
    d.script("document.querySelector('#take-list tr[data-take=\"cut\"] .take-repair').click();");
    let fixed = poll("the repaired take", Duration::from_secs(10), || {
        let r = row(&d);
        (r[3] == "complete").then_some(r)
    });
    assert_eq!(fixed[1].as_str().unwrap(), sound.frames.len().to_string(), "every frame kept: {fixed}");
    let after = frond_formats::scan_take(&std::fs::read(&path).unwrap()).unwrap();
    assert!(after.ended && after.torn_bytes == 0, "{after:?}");
    assert_eq!(after.frames, sound.frames);
    let said = d.script("return document.getElementById('control-result').textContent;");
    assert!(said.as_str().unwrap().contains("torn bytes at the end"), "{said}");
}

/// Issue 46: the page shows the mocap stage as `frond status` does: the capture triggers it
/// follows (and the last one, by name and sender) and the stage's timecode from LTC.
#[test]
fn the_page_shows_the_stage_triggers_and_timecode() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let Some((chromium, driver)) = browser() else { return };
    // Where the time goes, should a run be slow (one CI run took 84 s where 3 s is usual).
    let t0 = std::time::Instant::now();
    let step = |what: &str| eprintln!("[{:.1} s] {what}", t0.elapsed().as_secs_f64());
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("ltc.fifo");
    crate::ltc::mkfifo(&fifo);
    let port = std::net::UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let listen = format!("127.0.0.1:{port}");
    let daemon = Daemon::start(
        dir.path(),
        &["--source", "in-process", "--triggers", &listen, "--ltc", fifo.to_str().unwrap()],
    );
    step("daemon started");
    let stop = Arc::new(AtomicBool::new(false));
    let (writer, _) = crate::ltc::play(crate::ltc::PAL, &fifo, stop.clone());
    let sender = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    sender.send_to(&crate::triggers::capture_start("Scene 4 <b>take</b>", 0, 1), &listen).unwrap();
    assert!(wait_for(Duration::from_secs(10), || daemon.status().recording.is_some_and(|r| r.active)));
    step("recording started by the trigger");
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    step("console started");
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1200,760", &url);
    step("browser session started");
    let lines = poll("the stage's triggers and timecode", Duration::from_secs(15), || {
        let v = d.script(
            "const el = document.getElementById('stage-sync');
             return el.hidden ? null : [...el.children].map(c => c.textContent);",
        );
        let locked = v[1].as_str().is_some_and(|l| l.contains("locked at 25 fps"));
        locked.then_some(v)
    });
    let triggers = lines[0].as_str().unwrap();
    assert!(
        triggers.starts_with(&format!("triggers: following capture triggers on {listen} from any host")),
        "{lines}"
    );
    // The take's name as the master sent it, shown as text (the markup is not the page's).
    assert!(triggers.contains("last CaptureStart Scene 4 <b>take</b> from 127.0.0.1"), "{lines}");
    let html = d.script("return document.getElementById('stage-sync').innerHTML;");
    assert!(html.as_str().unwrap().contains("&lt;b&gt;take"), "{html}");
    let ltc = lines[1].as_str().unwrap();
    assert!(
        ltc.starts_with(&format!("timecode (LTC): locked at 25 fps from {}, last 10:00:0", fifo.display())),
        "{lines}"
    );
    step("page checked");
    // The switch pauses following, and says so; a start then records nothing; it follows again.
    let toggle = |want: &str| {
        let label = d.script(
            "const b = document.getElementById('triggers-toggle'); return b.hidden ? null : b.textContent;",
        );
        assert_eq!(label.as_str(), Some(want), "the trigger switch");
        d.script("document.getElementById('triggers-toggle').click();");
    };
    toggle("pause triggers");
    assert!(wait_for(Duration::from_secs(5), || daemon.status().triggers.is_some_and(|t| t.paused)));
    let paused = poll("the page shows the pause", Duration::from_secs(10), || {
        let v = d.script("return document.getElementById('stage-sync').children[0].textContent;");
        v.as_str().is_some_and(|l| l.starts_with("triggers: PAUSED")).then_some(v)
    });
    assert!(
        paused.as_str().unwrap().starts_with(&format!(
            "triggers: PAUSED: capture triggers on {listen} from any host are heard, not followed (0 starts missed)"
        )),
        "{paused}"
    );
    toggle("follow triggers");
    assert!(wait_for(Duration::from_secs(5), || daemon.status().triggers.is_some_and(|t| !t.paused)));
    step("trigger switch checked");
    stop.store(true, Ordering::Relaxed);
    writer.join().unwrap();
    step("LTC writer ended");
}
