//! The stage's health and the guided calibration from the page.

use std::time::Duration;

use frond_e2e::{Daemon, wait_for};
use frond_formats::rig_toml::CalibrationText;
use frond_webdriver::{Driver, browser, poll, start_session};
use serde_json::json;

use super::start_console;

#[test]
fn the_health_panel_shows_an_unplugged_glove_with_the_fix_within_a_second() {
    if !frond_e2e::fuse_available() {
        eprintln!("skipped: no /dev/fuse");
        return;
    }
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("vhid").join("hidraw-glove");
    // The glove goes away 5 s after its first report (the page is up by then), for 4 s. Its
    // reports carry the host's CLOCK_MONOTONIC, so the page measures glove-to-console latency.
    let (_glove, node, _out) = frond_e2e::start_vhid(&[
        "--sway",
        "--clock",
        "monotonic",
        "--rate",
        "1000",
        "--node",
        node.to_str().unwrap(),
        "--unplug-at-ms",
        "5000",
        "--unplug-ms",
        "4000",
    ]);
    let daemon = Daemon::start(dir.path(), &["--hand", &format!("glove=hid:{}", node.display())]);
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1000,700", &url);
    let problems =
        || d.script("return document.getElementById('problems').textContent;").as_str().unwrap().to_string();
    poll("the page's health panel", Duration::from_secs(10), || {
        let t = d.script("return document.getElementById('source').textContent;");
        t.as_str().filter(|s| s.contains("— connected")).map(|_| ())
    });
    assert!(!problems().contains("not connected"), "the glove is there: {}", problems());
    let glove = poll("the glove latency", Duration::from_secs(4), || {
        let v =
            d.script("return window.frondConsole.state.status && window.frondConsole.state.status.console;");
        (!v.is_null() && !v["glove_latency"].is_null()).then_some(v)
    });
    let (g50, d50) =
        (glove["glove_latency"]["p50_us"].as_f64().unwrap(), glove["latency"]["p50_us"].as_f64().unwrap());
    // The report comes before its publish: the glove's part is at least the delivery's.
    assert!(g50 >= d50 && g50 < 100_000.0, "glove p50 {g50} us, delivery p50 {d50} us");
    let shown = d.script("return document.getElementById('glove-latency').textContent;");
    assert!(shown.as_str().unwrap().starts_with("glove → console p50"), "{shown}");
    // The daemon sees the unplug; the page says so within a second, with the fix.
    assert!(
        wait_for(Duration::from_secs(15), || !daemon.status().source.connected),
        "the daemon never saw the glove go"
    );
    let lost_at = std::time::Instant::now();
    let said = poll("the unplug on the page", Duration::from_secs(5), || {
        let t = problems();
        t.contains("is not connected").then_some(t)
    });
    let took = lost_at.elapsed();
    assert!(took < Duration::from_secs(1), "the page showed the unplug after {took:?}");
    assert!(
        said.contains("hand source glove (fuse-hidraw") && said.contains("frond-vhid) is gone"),
        "{said}"
    );
    // And clears it when the glove is back.
    assert!(
        wait_for(Duration::from_secs(15), || daemon.status().source.connected),
        "the glove never came back"
    );
    poll("the problem to clear", Duration::from_secs(5), || {
        (!problems().contains("not connected")).then_some(())
    });
}

/// Sends `/frond/hand` messages (`t`, wrist pitch, yaw, roll, thumb g1, g2, g3) to the daemon's
/// OSC source on `port` at 100 Hz for `len`, each sample `at(k)`; `t` continues from `*t`.
fn send_hand(port: u16, t: &mut f64, len: Duration, at: impl Fn(usize) -> ([f32; 3], [f32; 3])) {
    use rosc::{OscMessage, OscPacket, OscType};
    let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let n = (len.as_secs_f64() * 100.0) as usize;
    for k in 0..n {
        let (w, g) = at(k);
        *t += 0.01;
        let mut args = vec![OscType::Double(*t)];
        args.extend(w.iter().chain(&g).map(|&v| OscType::Float(v)));
        let packet = OscPacket::Message(OscMessage { addr: "/frond/hand".into(), args });
        tx.send_to(&rosc::encoder::encode(&packet).unwrap(), ("127.0.0.1", port)).unwrap();
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn the_guided_calibration_measures_and_applies_a_calibration_from_the_page() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let port = std::net::UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let daemon = Daemon::start(dir.path(), &["--source", &format!("osc://127.0.0.1:{port}")]);
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1000,900", &url);
    poll("the page", Duration::from_secs(10), || {
        (d.script("return !!document.getElementById('cal-start');") == json!(true)).then_some(())
    });
    d.script(
        "document.getElementById('cal-user').value = 'pat';
         document.getElementById('cal-seconds').value = '0.8';
         document.getElementById('cal-start').click();",
    );
    let state = |d: &Driver| d.script("return window.frondConsole.state.calibration;");
    poll("the session", Duration::from_secs(10), || (state(&d)["running"] == json!(true)).then_some(()));
    // What the performer does in each step: a still neutral, then each wrist axis between its
    // extremes (each held 50 ms, so the 50 Hz polling sees both), then the thumb bent.
    let (nw, ng) = ([2.0f32, -3.0, 4.0], [10.0f32, 12.0, 8.0]);
    let extremes = [[-40.0f32, 50.0], [-30.0, 35.0], [-60.0, 70.0]];
    let bent = [60.0f32, 80.0, 70.0];
    let mut t = 0.0;
    // The live hand shows before any step.
    send_hand(port, &mut t, Duration::from_millis(300), |_| (nw, ng));
    poll("the live hand", Duration::from_secs(10), || {
        (state(&d)["live"]["fresh"] == json!(true)).then_some(())
    });
    for step in 0..5 {
        let mut t0 = t;
        let sender = std::thread::spawn(move || {
            send_hand(port, &mut t0, Duration::from_millis(1300), |k| {
                let high = (k / 5) % 2 == 1;
                match step {
                    0 => (nw, ng),
                    1..=3 => {
                        let mut w = nw;
                        w[step - 1] = extremes[step - 1][usize::from(high)];
                        (w, ng)
                    }
                    _ => (nw, if high { bent } else { ng }),
                }
            });
            t0
        });
        std::thread::sleep(Duration::from_millis(100));
        d.script("document.getElementById('cal-step').click();");
        poll(&format!("step {step} recorded"), Duration::from_secs(10), || {
            let s = state(&d);
            (s["recording"].is_null() && s["steps"][step]["samples"].as_u64().unwrap_or(0) > 10).then_some(())
        });
        t = sender.join().unwrap();
    }
    let s = poll("the result", Duration::from_secs(10), || {
        let s = state(&d);
        (!s["result"].is_null()).then_some(s)
    });
    // The calibration the page measured is what the performer did, worked out here: the
    // neutral as held, each wrist range its two extremes, each thumb range bent minus neutral.
    let toml = s["result"]["toml"].as_str().unwrap_or_else(|| panic!("no calibration: {}", s["result"]));
    let cal = frond_motion::Calibration::from_toml_str(toml).unwrap();
    assert_eq!(cal.id, "pat");
    let close = |a: f32, b: f32| (a - b).abs() < 1e-3;
    for k in 0..3 {
        assert!(close(cal.neutral_wrist_deg[k], nw[k]), "{cal:?}");
        assert!(close(cal.neutral_thumb_deg[k], ng[k]), "{cal:?}");
        assert!(close(cal.thumb_range_deg[k], bent[k] - ng[k]), "{cal:?}");
    }
    let ranges = cal.wrist_range_deg.unwrap_or_else(|| panic!("wrist ranges: {}", s["result"]));
    for k in 0..3 {
        assert!(close(ranges[k][0], extremes[k][0]) && close(ranges[k][1], extremes[k][1]), "{ranges:?}");
    }
    // The live hand against its ranges is on the page; applying it makes it the daemon's.
    let shown = d.script("return document.getElementById('cal-live').textContent;");
    assert!(shown.as_str().unwrap().contains("-40.0 … 50.0"), "{shown}");
    d.script("document.getElementById('cal-apply').click();");
    assert!(wait_for(Duration::from_secs(10), || daemon.status().calibration_id == "pat"), "not applied");
}
