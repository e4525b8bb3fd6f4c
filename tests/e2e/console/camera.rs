//! Issue 47: the console's camera panel on a real daemon whose hand is a camera (the real model
//! on fingerpose 0.1.0's photograph of a hand, as `webcam.rs` runs it): the page shows the
//! helper's picture with the hand drawn where the model found its landmarks, the angles the
//! daemon derived (those a second implementation computes from the same landmarks), the camera
//! and its rate; and no other site's page can read the picture or the angles.

use std::os::unix::fs::PermissionsExt;
use std::time::Duration;

use frond_e2e::{Daemon, Proc, wait_for};
use frond_webdriver::{browser, poll, start_session};
use serde_json::Value;

use super::{request, start_console};
use crate::webcam::{expected_sample, photo, run_offline, use_static_helper, world_of};

/// A daemon on the photograph (its two hands: `left`, the primary, and `right`, which the
/// photograph does not show; no filter; the static helper) with its picture kept, and a console
/// on loopback: the daemon, the console, its `ADDR`, the picture's file name and the model's
/// first frame of the photograph.
fn camera_console(dir: &std::path::Path) -> (Daemon, Proc, String, String, Value) {
    let mut lines = run_offline(&photo(), 1);
    use_static_helper(dir);
    let left = format!("left=webcam:{}?hand=left", photo().to_str().unwrap());
    let right = format!("right=webcam:{}?hand=right,element=leaf", photo().to_str().unwrap());
    let daemon =
        Daemon::start(dir, &["--hand", &left, "--hand", &right, "--rig", "flower", "--filter", "none"]);
    assert!(
        wait_for(Duration::from_secs(30), || daemon.status().source.reports >= 3),
        "{:?}",
        daemon.status()
    );
    // Status names the picture; it is in the daemon's socket directory, for no other user.
    let name = daemon.status().source.camera.and_then(|c| c.preview).expect("status names the picture");
    assert!(frond_protocol::paths::is_camera_preview_name(&name), "{name}");
    let file = daemon.socket_dir.join(&name);
    assert!(wait_for(Duration::from_secs(10), || file.is_file()), "{} is kept", file.display());
    let mode = std::fs::metadata(&file).unwrap().permissions().mode();
    assert_eq!(mode & 0o007, 0, "the picture is not world-readable: {mode:o}");
    let (console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
    (daemon, console, addr, name, lines.swap_remove(1))
}

/// `(r, g, b)` close to the helper's landmark magenta / bone green (JPEG moves colours a little).
fn magenta(c: &Value) -> bool {
    c[0].as_u64() > Some(150) && c[1].as_u64() < Some(110) && c[2].as_u64() > Some(150)
}
fn green(c: &Value) -> bool {
    c[1].as_u64() > Some(150) && c[0].as_u64() < Some(120) && c[2].as_u64() < Some(120)
}

#[test]
fn the_camera_panel_shows_the_hand_the_model_found_and_the_angles_the_daemon_derived() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (_daemon, _console, addr, _name, frame) = camera_console(dir.path());
    let want = expected_sample(&world_of(&frame), true);
    let image: Vec<f64> =
        frame["hands"][0]["image"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let d = start_session(
        &chromium,
        &driver,
        &dir.path().join("profile"),
        "1200,900",
        &format!("http://{addr}/"),
    );
    poll("the camera's picture on the page", Duration::from_secs(20), || {
        let n = d.script("return window.frondCamera.state.pictures;");
        (n.as_u64() >= Some(2)).then_some(())
    });
    // The photograph (480 x 640) at the panel's 320 pixels wide.
    let picture = d.script("return window.frondCamera.state.picture;");
    assert_eq!((picture["width"].as_u64(), picture["height"].as_u64()), (Some(320), Some(427)), "{picture}");
    // Each of the 21 landmarks, where the model found it in the (mirrored) frame, is drawn;
    // the middles of bones between them (a few cross others or a landmark's dot); and nothing
    // where there is no hand: the wall in the top corners.
    const BONES: [(usize, usize); 6] = [(2, 3), (6, 7), (7, 8), (10, 11), (14, 15), (18, 19)];
    let mut points: Vec<[f64; 2]> = (0..21).map(|i| [image[3 * i], image[3 * i + 1]]).collect();
    points.extend(
        BONES.iter().map(|&(a, b)| {
            [(image[3 * a] + image[3 * b]) / 2.0, (image[3 * a + 1] + image[3 * b + 1]) / 2.0]
        }),
    );
    points.extend([[0.03, 0.03], [0.97, 0.03]]);
    let colours = d.script(&format!("return window.frondCamera.rgbAt({});", serde_json::json!(points)));
    let colours = colours.as_array().unwrap();
    for (i, c) in colours[..21].iter().enumerate() {
        assert!(magenta(c), "landmark {i} at {:?}: {c}", points[i]);
    }
    let drawn = colours[21..27].iter().filter(|c| green(c)).count();
    assert!(drawn >= 5, "{drawn} of {} bones drawn green: {colours:?}", BONES.len());
    for (c, p) in colours[27..].iter().zip(&points[27..]) {
        assert!(!magenta(c) && !green(c), "{p:?}: {c}");
    }
    // The angles: the daemon's raw sample, as the second implementation computes them, while
    // the hand is in view (a busy machine may stall the helper past the daemon's 250 ms).
    let (raw, text) = poll("the hand in view with its angles", Duration::from_secs(15), || {
        let raw = d.script("return window.frondCamera.state.raw;");
        let text = d.script("return window.frondCamera.text();");
        let in_view = text[0].as_str().is_some_and(|t| t.ends_with("— hand in view"));
        (in_view && raw["fresh"] == true).then_some((raw, text))
    });
    let got: Vec<f64> = raw["wrist_deg"]
        .as_array()
        .unwrap()
        .iter()
        .chain(raw["thumb_deg"].as_array().unwrap())
        .map(|v| v.as_f64().unwrap())
        .collect();
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 0.01, "page {got:?} != expected {want:?}");
    }
    let text: Vec<&str> = text.as_array().unwrap().iter().map(|t| t.as_str().unwrap()).collect();
    assert_eq!(text[0], format!("left: video file {}, left hand — hand in view", photo().display()));
    assert!(text[1].contains(" fps, ") && text[1].contains("ms frame to sample (model "), "{text:?}");
    for (k, shown) in text[2..].iter().enumerate() {
        let v: f64 = shown.trim_end_matches('°').parse().unwrap_or(f64::NAN);
        assert!((v - want[k]).abs() <= 0.051, "angle {k}: {shown} vs {}", want[k]);
    }
    // A camera's long path wraps: nothing in the side panel reaches past its edge.
    let wide = d.script(
        "const a = document.querySelector('aside'), right = a.getBoundingClientRect().left + a.clientWidth;
         return [...a.querySelectorAll('*')].filter(e => e.getBoundingClientRect().right > right + 1).map(e => e.tagName + '#' + e.id);",
    );
    assert_eq!(wide, serde_json::json!([]), "elements wider than the side panel");
    // The other hand of the camera, picked: not in the photograph, and no angles (the daemon
    // gives the primary hand's only), said so.
    d.script(
        "[...document.querySelectorAll('#camera-pick button')].find(b => b.textContent === 'right').click();",
    );
    let text = d.script("return window.frondCamera.text();");
    assert_eq!(text[0], format!("right: video file {}, right hand — NO HAND in view", photo().display()));
    assert!(text.as_array().unwrap()[2..].iter().all(|t| t == "–"), "{text}");
    let note = d.script("return document.getElementById('camera-angles-note').textContent;");
    assert_eq!(note, "the angles are shown for the primary hand (left) only");
}

#[test]
fn no_other_sites_page_can_read_the_camera() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (_daemon, _console, addr, name, _) = camera_console(dir.path());
    let host = format!("Host: {addr}\r\n");
    let picture = format!("/api/camera/{name}");
    // The console's own page may read it; the answer says no other origin may.
    let (s, head, body) = request(&addr, "GET", &picture, &host, "");
    assert_eq!(s, 200, "{head}");
    assert!(head.contains("Content-Type: image/jpeg") && body.len() > 1000, "{head}");
    assert!(head.contains("Cross-Origin-Resource-Policy: same-origin"), "{head}");
    // Another site's request (Fetch Metadata), a rebinding name, another file's name.
    let cross =
        format!("{host}Sec-Fetch-Site: cross-site\r\nSec-Fetch-Mode: no-cors\r\nSec-Fetch-Dest: image\r\n");
    assert_eq!(request(&addr, "GET", &picture, &cross, "").0, 403);
    let port = addr.rsplit(':').next().unwrap();
    assert_eq!(request(&addr, "GET", &picture, &format!("Host: evil.test:{port}\r\n"), "").0, 403);
    for other in ["/api/camera/control.sock", "/api/camera/..%2fcontrol.sock", "/api/camera/webcam-99.jpg"] {
        let (s, _, body) = request(&addr, "GET", other, &host, "");
        assert_eq!(s, 404, "{other}: {body}");
    }
    // A real browser on another site's page.
    let d = super::hostile::attack(
        &chromium,
        &driver,
        &dir.path().join("profile"),
        attacker_page(&addr, &picture),
    );
    let results = d.script("return window.results");
    eprintln!("attacker's page: {results}");
    for k in ["fetch-picture", "fetch-angles"] {
        assert!(results[k].as_str().unwrap_or("").starts_with("error"), "{k}: {results}");
    }
    assert_eq!(results["no-cors"], "opaque", "{results}");
    assert_eq!(results["img"], "refused", "{results}");
    // The same page on the console's own origin can (so the refusals above are the console's).
    d.cmd("POST", "/url", Some(serde_json::json!({ "url": format!("http://{addr}/") })));
    let own = d.async_script(&format!(
        "const done = arguments[arguments.length - 1];
         fetch('{picture}').then(r => r.blob()).then(b => createImageBitmap(b)).then(i => done(i.width), e => done('error: ' + e));"
    ));
    assert_eq!(own, serde_json::json!(320), "the console's own page reads its picture");
}

/// Another site's page trying to read the picture and the angles every way a page can.
fn attacker_page(console: &str, picture: &str) -> String {
    format!(
        r#"<!doctype html><html><body><h1>cat pictures</h1>
<script>
window.results = {{}};
const tries = [];
const at = (k, p) => tries.push(p.then(v => {{ window.results[k] = v; }}, e => {{ window.results[k] = 'error: ' + e; }}));
at('fetch-picture', fetch('http://{console}{picture}').then(r => r.blob()).then(b => 'read ' + b.size));
at('fetch-angles', fetch('http://{console}/api/camera').then(r => r.text()));
at('no-cors', fetch('http://{console}{picture}', {{mode: 'no-cors'}}).then(r => r.type));
// An image of it, then its pixels through a canvas.
at('img', new Promise(res => {{
  const i = new Image();
  i.onerror = () => res('refused');
  i.onload = () => {{
    const c = document.createElement('canvas'); c.width = 4; c.height = 4;
    const g = c.getContext('2d'); g.drawImage(i, 0, 0);
    try {{ res('read ' + g.getImageData(0, 0, 1, 1).data.join(',')); }} catch (e) {{ res('loaded, pixels refused'); }}
  }};
  i.src = 'http://{console}{picture}';
}}));
Promise.all(tries).then(() => {{ window.done = true; }});
</script></body></html>"#
    )
}
