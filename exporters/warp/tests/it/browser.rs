//! Headless-browser test of `frond-warp serve` (Chromium through WebDriver, `frond-webdriver`).
//! Checks that the page
//! loads, that frames keep changing, that a control changes the output, and takes a screenshot:
//! into the test's temporary directory, or, with `FROND_UPDATE_SCREENSHOT=1`, over
//! `exporters/warp/screenshot.png` for the README (so a test run leaves the work tree clean).
//!
//! Without chromium/chromedriver the test prints why and skips (install them with
//! `exporters/warp/tests/install-browser.sh`); under `CI=true` or `FROND_REQUIRE_BROWSER=1` a
//! missing browser fails the test.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use frond_webdriver::{Driver, Guard, base64_decode, browser, poll, start_session};
use serde_json::{Value, json};

/// What the warp pages' tests ask of the browser.
trait WarpPage {
    fn diff_to_still(&self) -> f64;
    fn set_control(&self, id: &str, value: f64);
}

impl WarpPage for Driver {
    /// Mean absolute difference between the canvas and the still picture, per channel value.
    fn diff_to_still(&self) -> f64 {
        self.async_script(
            "const done = arguments[arguments.length - 1];
             fetch('/still').then(r => r.arrayBuffer()).then(b => {
               const s = new Uint8Array(b);
               const c = document.getElementById('view');
               const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
               let diff = 0;
               for (let i = 0; i < d.length; i++) diff += Math.abs(d[i] - s[i]);
               done(diff / d.length);
             });",
        )
        .as_f64()
        .expect("number")
    }
    fn set_control(&self, id: &str, value: f64) {
        self.script(&format!(
            "const el = document.getElementById('{id}'); el.value = {value}; el.dispatchEvent(new Event('input'));"
        ));
    }
}

/// Starts `frond-warp ARGS --listen 127.0.0.1:0` and returns it with the URL it prints.
fn start_server(args: &[&str]) -> (Guard, String) {
    let mut server = Command::new(env!("CARGO_BIN_EXE_frond-warp"))
        .args(args)
        .args(["--listen", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond-warp serve");
    let stdout = server.stdout.take().unwrap();
    let guard = Guard(server);
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).unwrap();
    let url = line
        .trim()
        .strip_prefix("listening on ")
        .unwrap_or_else(|| panic!("unexpected: {line:?}"))
        .to_string();
    assert!(url.starts_with("http://127.0.0.1:"), "{url}");
    (guard, url)
}

/// Saves a screenshot: over `exporters/warp/NAME` with `FROND_UPDATE_SCREENSHOT=1` (for the
/// README), else into the temporary directory.
fn save_screenshot(d: &Driver, name: &str) {
    let png = d.screenshot_png();
    let shot = if std::env::var_os("FROND_UPDATE_SCREENSHOT").is_some_and(|v| v == "1") {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(name)
    } else {
        std::env::temp_dir().join(format!("frond-warp-{}-{name}", std::process::id()))
    };
    std::fs::write(&shot, &png).unwrap();
    eprintln!("screenshot: {}", shot.display());
}

fn images() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/images")
}

#[test]
fn page_loads_animates_and_controls_change_the_output() {
    let Some((chromium, driver)) = browser() else { return };
    let images = images();
    let tmp = tempfile::tempdir().unwrap();
    // An empty socket directory: no daemon, so the page must say it uses the procedural wind.
    let sockets = tmp.path().join("sockets");
    std::fs::create_dir_all(&sockets).unwrap();
    let [image, layer, scale] =
        ["grass.png", "grass-mask.png", "grass-scale.png"].map(|f| images.join(f).display().to_string());
    let sockets = sockets.display().to_string();
    let (_server, url) = start_server(&[
        "serve",
        "--image",
        &image,
        "--layer",
        &layer,
        "--scale-map",
        &scale,
        "--strength",
        "0.9",
        "--interval",
        "0.6",
        "--socket-dir",
        &sockets,
    ]);
    let d = start_session(&chromium, &driver, &tmp.path().join("profile"), "1100,640", &url);

    // The page loads.
    assert_eq!(d.cmd("GET", "/title", None), json!("frond-warp preview"));
    let daemon = poll("the daemon state", Duration::from_secs(10), || {
        let t = d.script("return document.getElementById('daemon').textContent;");
        t.as_str().filter(|s| s.contains("procedural")).map(str::to_string)
    });
    assert!(daemon.contains("no daemon"), "{daemon}");

    // Frames keep changing: the frame number advances and the picture's hash changes.
    let first = poll("a first frame", Duration::from_secs(20), || {
        let s = d.script("return window.frondStats;");
        (s["shown"].as_u64().unwrap_or(0) > 0).then_some(s)
    });
    let later = poll("changing frames", Duration::from_secs(20), || {
        let s = d.script("return window.frondStats;");
        (s["shown"].as_u64() > Some(first["shown"].as_u64().unwrap() + 10) && s["hash"] != first["hash"])
            .then_some(s)
    });
    assert!(later["lastFrame"].as_u64() > first["lastFrame"].as_u64());

    // A control changes the output: with lambda = 0 every displacement is zero (Eq. 5) and the
    // canvas shows the still picture exactly; raising it again makes the picture move.
    poll("wind moving the picture", Duration::from_secs(20), || (d.diff_to_still() > 0.01).then_some(()));
    d.set_control("lambda", 0.0);
    poll("lambda = 0 showing the still picture", Duration::from_secs(10), || {
        (d.diff_to_still() == 0.0).then_some(())
    });
    d.set_control("lambda", 40.0);
    poll("lambda = 40 moving the picture again", Duration::from_secs(20), || {
        (d.diff_to_still() > 0.01).then_some(())
    });
    // A bad value is refused with its name and range, shown on the page.
    d.script("fetch('/params', {method: 'POST', body: JSON.stringify({gamma: 3})}).then(async r => document.getElementById('error').textContent = await r.text());");
    let err = poll("the error message", Duration::from_secs(5), || {
        let t = d.script("return document.getElementById('error').textContent;");
        t.as_str().filter(|s| !s.is_empty()).map(str::to_string)
    });
    assert!(err.contains("gamma = 3 is out of range (allowed: 0.01 to 1)"), "{err}");
    d.script("document.getElementById('error').textContent = '';");

    // Screenshot for the README.
    std::thread::sleep(Duration::from_millis(1500));
    save_screenshot(&d, "screenshot.png");
}

/// The canvas's pixels (RGBA), read back from the page.
fn canvas_pixels(d: &Driver) -> Vec<u8> {
    let v = d.script(
        "const c = document.getElementById('view');
         const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
         let s = ''; for (let i = 0; i < px.length; i += 8192) s += String.fromCharCode.apply(null, px.subarray(i, i + 8192));
         return btoa(s);",
    );
    base64_decode(v.as_str().expect("base64"))
}

/// Even-odd point in polygon, written here independently of frond-cage.
fn inside(poly: &[[f64; 2]], x: f64, y: f64) -> bool {
    let mut c = false;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if (a[1] > y) != (b[1] > y) && x < a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]) {
            c = !c;
        }
    }
    c
}

/// Intersection over union of the plant (pixels that differ from the background) and `poly`.
fn plant_iou(rgba: &[u8], background: &[u8], w: usize, poly: &[[f64; 2]]) -> f64 {
    let (mut both, mut either) = (0usize, 0usize);
    for (i, (p, b)) in rgba.chunks_exact(4).zip(background.chunks_exact(3)).enumerate() {
        let plant = (0..3).map(|c| (p[c] as i32 - b[c] as i32).abs()).sum::<i32>() > 30;
        let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
        let sketch = inside(poly, x, y);
        both += (plant && sketch) as usize;
        either += (plant || sketch) as usize;
    }
    both as f64 / either.max(1) as f64
}

#[test]
fn cage_page_morphs_the_plant_towards_a_stroke_drawn_with_the_pointer() {
    let Some((chromium, driver)) = browser() else { return };
    let images = images();
    let tmp = tempfile::tempdir().unwrap();
    let sockets = tmp.path().join("sockets");
    std::fs::create_dir_all(&sockets).unwrap();
    let [image, layer] = ["shrub-background.png", "shrub.png"].map(|f| images.join(f).display().to_string());
    let sockets = sockets.display().to_string();
    let (_server, url) = start_server(&[
        "serve",
        "--mode",
        "cage",
        "--image",
        &image,
        "--layer",
        &layer,
        "--morph-s",
        "0.6",
        "--socket-dir",
        &sockets,
    ]);
    let d = start_session(&chromium, &driver, &tmp.path().join("profile"), "1200,760", &url);
    assert_eq!(d.cmd("GET", "/title", None), json!("frond-warp cage preview"));
    poll("a first frame", Duration::from_secs(20), || {
        (d.script("return window.frondStats.shown;").as_u64() > Some(0)).then_some(())
    });
    poll("the daemon state", Duration::from_secs(10), || {
        let t = d.script("return document.getElementById('daemon').textContent;");
        t.as_str().filter(|s| s.contains("no daemon")).map(str::to_string)
    });
    // The cage tree is drawn over the picture: the overlay has the crown's colour on it.
    let crown_px = d.script(
        "const o = document.getElementById('overlay'); const px = o.getContext('2d').getImageData(0, 0, o.width, o.height).data;
         let n = 0; for (let i = 0; i < px.length; i += 4) if (px[i] === 0xff && px[i + 1] === 0xd7 && px[i + 2] === 0x5e) n++; return n;",
    );
    assert!(crown_px.as_u64() > Some(200), "crown outline pixels on the overlay: {crown_px}");

    let background = image::open(images.join("shrub-background.png")).unwrap().to_rgb8().into_raw();
    let (w, _h) = (320usize, 240usize);
    let heart: Value =
        serde_json::from_str(&std::fs::read_to_string(images.join("shrub-heart-sketch.json")).unwrap())
            .unwrap();
    let heart: Vec<[f64; 2]> = heart["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()])
        .collect();
    let before = plant_iou(&canvas_pixels(&d), &background, w, &heart);

    // Draw the heart with the mouse: real pointer events from WebDriver's input actions.
    let rect = d.script("const r = document.getElementById('overlay').getBoundingClientRect(); return [r.left, r.top, r.width / 320];");
    let (left, top, scale) =
        (rect[0].as_f64().unwrap(), rect[1].as_f64().unwrap(), rect[2].as_f64().unwrap());
    let at = |p: [f64; 2]| {
        json!({ "type": "pointerMove", "duration": 0, "origin": "viewport",
        "x": (left + p[0] * scale).round() as i64, "y": (top + p[1] * scale).round() as i64 })
    };
    let mut actions = vec![at(heart[0]), json!({ "type": "pointerDown", "button": 0 })];
    actions.extend(heart.iter().step_by(3).skip(1).map(|&p| at(p)));
    actions.push(at(heart[heart.len() - 1]));
    actions.push(json!({ "type": "pointerUp", "button": 0 }));
    d.cmd(
        "POST",
        "/actions",
        Some(json!({ "actions": [{ "type": "pointer", "id": "mouse", "parameters": { "pointerType": "mouse" }, "actions": actions }] })),
    );
    poll("the sketch sent", Duration::from_secs(5), || {
        let e = d.script("return document.getElementById('error').textContent;");
        assert_eq!(e, json!(""), "the page refused the stroke");
        (d.script("return window.frondStats.sent;").as_u64() == Some(1)).then_some(())
    });
    // The morph plays to its end, and the page shows its final frame.
    poll("the morph's end", Duration::from_secs(20), || {
        let s = d.script("return window.frondStats;");
        (s["drive"] == json!("sketch")
            && s["t"].as_f64() == Some(1.0)
            && s["lastFrame"].as_u64() >= s["serverFrame"].as_u64())
        .then_some(())
    });
    std::thread::sleep(Duration::from_millis(300));
    let after = plant_iou(&canvas_pixels(&d), &background, w, &heart);
    eprintln!("plant IoU with the drawn heart: before {before:.3}, after {after:.3}");
    assert!(after > before + 0.1 && after > 0.85, "IoU before {before:.3}, after {after:.3}");
    let frechet = poll("the quality", Duration::from_secs(5), || {
        let t = d.script("return document.getElementById('frechet').textContent;");
        t.as_str().filter(|s| s.ends_with(" px")).map(str::to_string)
    });
    let frechet: f64 = frechet.trim_end_matches(" px").parse().unwrap();
    assert!(frechet < 20.0, "Frechet distance to the sketch {frechet} px");
    save_screenshot(&d, "screenshot-cage.png");

    // A bad sketch is refused with its problem named on the page.
    d.script("window.frondSendSketch({version: 1, closed: true, points: [[1, 1]]});");
    let err = poll("the error message", Duration::from_secs(5), || {
        let t = d.script("return document.getElementById('error').textContent;");
        t.as_str().filter(|s| !s.is_empty()).map(str::to_string)
    });
    assert!(err.contains("a closed sketch has 3 to"), "{err}");

    // Escape returns to the rest shape: the still picture exactly.
    d.cmd(
        "POST",
        "/actions",
        Some(json!({ "actions": [{ "type": "key", "id": "keyboard", "actions": [
            { "type": "keyDown", "value": "\u{E00C}" }, { "type": "keyUp", "value": "\u{E00C}" }] }] })),
    );
    poll("the rest shape after Escape", Duration::from_secs(10), || {
        (d.script("return window.frondStats.drive;") == json!("rest") && d.diff_to_still() == 0.0)
            .then_some(())
    });
}
