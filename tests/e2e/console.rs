//! `frond-console` on a real daemon (issue 19): the page's 3D scene follows the live poses
//! (bones' world positions read back from the page against forward kinematics of the poses the
//! page received, computed here from the rig's heights and the protocol's rotation convention),
//! the recording controls leave a take on disk, and the access rules refuse what they must.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::Duration;

use frond_e2e::{Daemon, Proc, bin, wait_for};
use frond_motion::mesh::PlantModel;
use frond_protocol::ElementKind;
use frond_protocol::convention::joint_matrix;
use frond_webdriver::{Driver, browser, poll, start_session};
use serde_json::{Value, json};

/// Starts `frond-console ARGS` on `daemon` and returns it with its URL and the whole first line.
fn start_console(daemon: &Daemon, args: &[&str]) -> (Proc, String, String) {
    let mut child = Command::new(bin("frond-console"))
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .arg("--takes-dir")
        .arg(&daemon.takes_dir)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond-console");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let url = line
        .strip_prefix("frond-console: ")
        .and_then(|r| r.split_whitespace().next())
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
        .to_string();
    (Proc { child, name: "frond-console".into() }, url, line)
}

/// One request to `addr` with extra header lines; status, head and body.
fn request(addr: &str, method: &str, path: &str, headers: &str, body: &str) -> (u16, String, String) {
    let mut s = TcpStream::connect(addr).expect("connect to frond-console");
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\n{headers}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let text = String::from_utf8_lossy(&raw).to_string();
    let (head, body) = text.split_once("\r\n\r\n").expect("HTTP head");
    let status = head.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    (status, head.to_string(), body.to_string())
}

/// A rigid frame: rotation (row-major) and origin.
#[derive(Debug, Clone, Copy)]
struct Frame {
    rot: [[f64; 3]; 3],
    pos: [f64; 3],
}

impl Frame {
    const IDENTITY: Frame = Frame { rot: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], pos: [0.0; 3] };

    /// `self * T(offset) * R(m)`: a child frame at `offset` in this frame, turned by `m`.
    fn child(&self, offset: [f64; 3], m: [[f64; 3]; 3]) -> Frame {
        let mut pos = self.pos;
        for (r, p) in pos.iter_mut().enumerate() {
            *p += (0..3).map(|k| self.rot[r][k] * offset[k]).sum::<f64>();
        }
        let rot =
            std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| self.rot[r][k] * m[k][c]).sum()));
        Frame { rot, pos }
    }
}

/// The rotation matrix of a unit quaternion `[x, y, z, w]`.
fn quat_matrix([x, y, z, w]: [f32; 4]) -> [[f64; 3]; 3] {
    let (x, y, z, w) = (f64::from(x), f64::from(y), f64::from(z), f64::from(w));
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// The frames of a 4-joint chain from `base`: joint `i` sits at `heights[i] - heights[i - 1]`
/// along its parent's +Y (joint 0 at `heights[0]`), turned by `joint_matrix` of its
/// `[pitch, yaw, roll]` relative to its parent (the protocol's convention).
fn chain(base: Frame, heights: &[f32; 4], joints_deg: &[[f32; 3]; 4]) -> [Frame; 4] {
    let mut out = [base; 4];
    let mut parent = base;
    for i in 0..4 {
        let step = f64::from(heights[i]) - if i == 0 { 0.0 } else { f64::from(heights[i - 1]) };
        out[i] = parent.child([0.0, step, 0.0], joint_matrix(joints_deg[i]));
        parent = out[i];
    }
    out
}

fn joints_of(v: &Value) -> [[f32; 3]; 4] {
    std::array::from_fn(|i| std::array::from_fn(|k| v[i][k].as_f64().unwrap() as f32))
}

/// Reads `snapshot(element)` from the page until it has one, and checks every bone set of it
/// against forward kinematics (here, from the rig's model and the poses the page received);
/// returns the element's joints.
fn check_bones(d: &Driver, element: u16, model: &PlantModel) -> [[f32; 3]; 4] {
    let snap = poll(&format!("a snapshot of element {element}"), Duration::from_secs(30), || {
        let v = d
            .script(&format!("return window.frondConsole ? window.frondConsole.snapshot({element}) : null;"));
        (!v.is_null()).then_some(v)
    });
    let joints = joints_of(&snap["pose"]["j"]);
    let main = chain(Frame::IDENTITY, &model.skeleton.heights_m, &joints_of(&snap["main"]["j"]));
    // The chains the element drives: the main skeleton, or each instance of a rig element
    // (its layer id is the element's index + 1), hung from its attach joint.
    let want: Vec<[Frame; 4]> = if element == 0 {
        vec![main]
    } else {
        model
            .elements
            .iter()
            .filter(|e| e.element + 1 == usize::from(element))
            .map(|e| {
                let offset = e.offset_m.map(f64::from);
                let attach = main[usize::from(e.attach_joint)].child(offset, quat_matrix(e.rotation));
                chain(attach, &e.skeleton.heights_m, &joints)
            })
            .collect()
    };
    let sets = snap["bones"].as_array().unwrap();
    assert_eq!(sets.len(), want.len(), "bone sets of element {element}");
    let tol = 1e-4 * f64::from(model.skeleton.heights_m[3]);
    for (s, (set, frames)) in sets.iter().zip(&want).enumerate() {
        for (i, f) in frames.iter().enumerate() {
            for k in 0..3 {
                let got = set[i][k].as_f64().unwrap();
                assert!(
                    (got - f.pos[k]).abs() <= tol,
                    "element {element} set {s} joint {i} axis {k}: page {got}, forward kinematics {} (pose {joints:?})",
                    f.pos[k]
                );
            }
        }
    }
    joints
}

fn model(rig: &str) -> PlantModel {
    let loaded = frond_motion::rig_files::embedded_rig(rig).unwrap().unwrap();
    frond_motion::rig_files::plant_model(&loaded).unwrap()
}

fn heights(d: &Driver) -> [f64; 4] {
    let h = d.async_script(
        "const done = arguments[arguments.length - 1]; fetch('/api/scene').then(r => r.json()).then(m => done(m.heights_m));",
    );
    std::array::from_fn(|i| h[i].as_f64().unwrap())
}

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
    let scan = frond_motion::scan_take(&bytes).expect("a sound take");
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
    let main: Vec<_> = scan.frames.iter().filter(|f| f.element == 0).map(|f| f.pose).collect();
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
        .filter(|f| f.element == 0 && f.flags & frond_protocol::PoseFlags::HELD.0 != 0)
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

/// Saves a screenshot: over `exporters/console/NAME` with `FROND_UPDATE_SCREENSHOT=1` (the
/// README's picture), else into the temporary directory.
fn save_screenshot(d: &Driver, name: &str) {
    let png = d.screenshot_png();
    let shot = if std::env::var_os("FROND_UPDATE_SCREENSHOT").is_some_and(|v| v == "1") {
        frond_e2e::repo_root().join("exporters/console").join(name)
    } else {
        std::env::temp_dir().join(format!("frond-console-{}-{name}", std::process::id()))
    };
    std::fs::write(&shot, &png).unwrap();
    eprintln!("screenshot: {}", shot.display());
}

#[test]
fn beyond_loopback_every_request_needs_the_token_and_control_needs_the_origin() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let token = "tok-0123456789abcdef";
    std::fs::write(dir.path().join("token"), format!("{token}\n")).unwrap();
    let token_file = dir.path().join("token");
    let (_console, url, line) =
        start_console(&daemon, &["--listen", "0.0.0.0:0", "--token-file", token_file.to_str().unwrap()]);
    assert!(
        line.contains("?token=<the token in") && !line.contains(token),
        "the file's token is not printed: {line}"
    );
    let port = url.split("HOST:").nth(1).and_then(|r| r.split('/').next()).expect(&url).to_string();
    let addr = format!("127.0.0.1:{port}");
    let host = format!("Host: {addr}\r\n");
    let (s, _, body) = request(&addr, "GET", "/", &host, "");
    assert_eq!(s, 401, "{body}");
    assert!(body.contains("token"), "{body}");
    let (s, _, _) = request(&addr, "GET", "/api/hello?token=wrong-0123456789abcdef", &host, "");
    assert_eq!(s, 401);
    let (s, head, _) = request(&addr, "GET", &format!("/?token={token}"), &host, "");
    assert_eq!(s, 200);
    assert!(head.contains(&format!("Set-Cookie: frond_token={token}")), "{head}");
    let cookie = format!("{host}Cookie: frond_token={token}\r\n");
    let (s, _, _) = request(&addr, "GET", "/api/status", &cookie, "");
    assert_eq!(s, 200);
    // A control action: refused without the token, and from another site's page.
    let mark = r#"{"label":"from the console"}"#;
    let (s, _, _) = request(&addr, "POST", "/api/mark", &host, mark);
    assert_eq!(s, 401);
    let evil = format!("{cookie}Origin: http://evil.example\r\n");
    let (s, _, body) = request(&addr, "POST", "/api/mark", &evil, mark);
    assert_eq!(s, 403, "{body}");
    // With the token: the daemon answers (no recording: a mark is refused as wrong state, or
    // taken; either way it is the daemon's answer, not the console's refusal).
    let bearer = format!("{host}Authorization: Bearer {token}\r\n");
    let (s, _, body) = request(&addr, "POST", "/api/mark", &bearer, mark);
    assert!(s == 200 || (s == 409 && body.contains("the daemon refused")), "{s} {body}");
    assert!(wait_for(Duration::from_secs(5), || daemon.status().ticks > 0));
}

#[test]
fn on_loopback_another_host_name_or_origin_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
    let host = format!("Host: {addr}\r\n");
    let (s, _, body) = request(&addr, "GET", "/api/hello", &host, "");
    assert_eq!(s, 200, "{body}");
    let hello: Value = serde_json::from_str(&body).unwrap();
    assert_eq!(hello["type"], "hello");
    // DNS rebinding: a page on another name that resolves to 127.0.0.1.
    let (s, _, body) = request(&addr, "GET", "/api/hello", "Host: rebind.example:80\r\n", "");
    assert_eq!(s, 403, "{body}");
    // A control action needs the page's own Origin.
    let (s, _, _) = request(&addr, "POST", "/api/record/stop", &host, "");
    assert_eq!(s, 403);
    let other = format!("{host}Origin: http://evil.example\r\n");
    let (s, _, _) = request(&addr, "POST", "/api/record/stop", &other, "");
    assert_eq!(s, 403);
    let own = format!("{host}Origin: http://{addr}\r\n");
    let (s, _, body) = request(&addr, "POST", "/api/record/stop", &own, "");
    assert_eq!(s, 409, "not recording: the daemon's own refusal: {body}");
    assert!(body.contains("no take is being recorded"), "{body}");
    let (s, _, body) = request(&addr, "POST", "/api/record/start", &own, r#"{"name":"../x"}"#);
    assert_eq!(s, 400, "{body}");
    let (s, _, _) = request(&addr, "GET", "/nothing", &host, "");
    assert_eq!(s, 404);
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
fn the_health_panel_shows_an_unplugged_glove_with_the_fix_within_a_second() {
    if !frond_e2e::fuse_available() {
        eprintln!("skipped: no /dev/fuse");
        return;
    }
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("vhid").join("hidraw-glove");
    // The glove goes away 5 s after its first report (the page is up by then), for 4 s.
    let (_glove, node, _out) = frond_e2e::start_vhid(&[
        "--sway",
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
        let ids: Vec<u16> = daemon
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

/// `GET path` from the console at `url`, the body.
fn request_json(url: &str, path: &str) -> String {
    let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
    let (s, _, body) = request(&addr, "GET", path, &format!("Host: {addr}\r\n"), "");
    assert_eq!(s, 200, "{path}: {body}");
    body
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
