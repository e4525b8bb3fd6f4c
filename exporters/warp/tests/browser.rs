//! Headless-browser test of `frond-warp serve`: Debian's Chromium driven through chromedriver's
//! W3C WebDriver HTTP API (a tiny client over `TcpStream`, loopback only). Checks that the page
//! loads, that frames keep changing, that a control changes the output, and takes a screenshot:
//! into the test's temporary directory, or, with `FROND_UPDATE_SCREENSHOT=1`, over
//! `exporters/warp/screenshot.png` for the README (so a test run leaves the work tree clean).
//!
//! Without chromium/chromedriver the test prints why and skips (install them with
//! `exporters/warp/tests/install-browser.sh`); under `CI=true` or `FROND_REQUIRE_BROWSER=1` a
//! missing browser fails the test.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

/// Kills a child process that this test started when dropped.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn find(names: &[&str]) -> Option<PathBuf> {
    for name in names {
        let p = Path::new(name);
        if p.is_absolute() && p.exists() {
            return Some(p.to_path_buf());
        }
        if let Some(paths) = std::env::var_os("PATH") {
            for dir in std::env::split_paths(&paths) {
                let c = dir.join(name);
                if c.is_file() {
                    return Some(c);
                }
            }
        }
    }
    None
}

fn browser_required() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
        || std::env::var("FROND_REQUIRE_BROWSER").is_ok_and(|v| v == "1" || v == "true")
}

/// One HTTP/1.1 request to `127.0.0.1:port`; returns status and body.
fn http(port: u16, method: &str, path: &str, body: Option<&Value>) -> std::io::Result<(u16, Vec<u8>)> {
    let mut s = TcpStream::connect(("127.0.0.1", port))?;
    s.set_read_timeout(Some(Duration::from_secs(60)))?;
    let payload = body.map(|b| b.to_string()).unwrap_or_default();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json; charset=utf-8\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{payload}",
        payload.len()
    )?;
    let mut r = BufReader::new(s);
    let mut status_line = String::new();
    r.read_line(&mut status_line)?;
    let status: u16 = status_line.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    let mut chunked = false;
    let mut length = None;
    loop {
        let mut line = String::new();
        if r.read_line(&mut line)? == 0 || line == "\r\n" {
            break;
        }
        let lower = line.to_ascii_lowercase();
        if lower.starts_with("transfer-encoding:") && lower.contains("chunked") {
            chunked = true;
        } else if let Some(v) = lower.strip_prefix("content-length:") {
            length = v.trim().parse::<usize>().ok();
        }
    }
    let mut out = Vec::new();
    if chunked {
        loop {
            let mut size = String::new();
            r.read_line(&mut size)?;
            let n = usize::from_str_radix(size.trim().split(';').next().unwrap_or("0"), 16).unwrap_or(0);
            if n == 0 {
                break;
            }
            let mut buf = vec![0; n + 2];
            r.read_exact(&mut buf)?;
            out.extend_from_slice(&buf[..n]);
        }
    } else if let Some(n) = length {
        out.resize(n, 0);
        r.read_exact(&mut out)?;
    } else {
        r.read_to_end(&mut out)?;
    }
    Ok((status, out))
}

struct Driver {
    port: u16,
    session: String,
}

impl Driver {
    fn cmd(&self, method: &str, what: &str, body: Option<Value>) -> Value {
        let path = format!("/session/{}{what}", self.session);
        let (status, bytes) = http(self.port, method, &path, body.as_ref()).expect("webdriver request");
        let v: Value = serde_json::from_slice(&bytes).expect("webdriver JSON");
        assert_eq!(status, 200, "{method} {what}: {v}");
        v["value"].clone()
    }
    fn script(&self, src: &str) -> Value {
        self.cmd("POST", "/execute/sync", Some(json!({ "script": src, "args": [] })))
    }
    fn async_script(&self, src: &str) -> Value {
        self.cmd("POST", "/execute/async", Some(json!({ "script": src, "args": [] })))
    }
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

fn poll<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

fn base64_decode(s: &str) -> Vec<u8> {
    let val = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let mut out = Vec::new();
    let (mut acc, mut bits) = (0u32, 0);
    for c in s.bytes() {
        if let Some(v) = val(c) {
            acc = (acc << 6) | v;
            bits += 6;
            if bits >= 8 {
                bits -= 8;
                out.push((acc >> bits) as u8);
                acc &= (1 << bits) - 1;
            }
        }
    }
    out
}

#[test]
fn page_loads_animates_and_controls_change_the_output() {
    let chromium = find(&["chromium", "chromium-browser", "/usr/bin/chromium"]);
    let driver = find(&["chromedriver", "/usr/bin/chromedriver"]);
    let (Some(chromium), Some(driver)) = (chromium, driver) else {
        let msg = "chromium and/or chromedriver not found; install them with exporters/warp/tests/install-browser.sh";
        if browser_required() {
            panic!("{msg} (required because CI=true or FROND_REQUIRE_BROWSER=1)");
        }
        println!("SKIPPED browser test: {msg}");
        eprintln!("SKIPPED browser test: {msg}");
        return;
    };

    let images = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/images");
    let tmp = tempfile::tempdir().unwrap();
    // An empty socket directory: no daemon, so the page must say it uses the procedural wind.
    let sockets = tmp.path().join("sockets");
    std::fs::create_dir_all(&sockets).unwrap();
    let mut server = Command::new(env!("CARGO_BIN_EXE_frond-warp"))
        .args(["serve", "--image"])
        .arg(images.join("grass.png"))
        .arg("--layer")
        .arg(images.join("grass-mask.png"))
        .arg("--scale-map")
        .arg(images.join("grass-scale.png"))
        .args(["--strength", "0.9", "--interval", "0.6", "--listen", "127.0.0.1:0", "--socket-dir"])
        .arg(&sockets)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond-warp serve");
    let stdout = server.stdout.take().unwrap();
    let _server = Guard(server);
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).unwrap();
    let url = line
        .trim()
        .strip_prefix("listening on ")
        .unwrap_or_else(|| panic!("unexpected: {line:?}"))
        .to_string();
    assert!(url.starts_with("http://127.0.0.1:"), "{url}");

    let port = free_port();
    let wd = Command::new(&driver)
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start chromedriver");
    let _wd = Guard(wd);
    poll("chromedriver", Duration::from_secs(30), || {
        http(port, "GET", "/status", None)
            .ok()
            .and_then(|(_, b)| serde_json::from_slice::<Value>(&b).ok())
            .filter(|v| v["value"]["ready"] == json!(true))
    });
    let profile = tmp.path().join("profile");
    let caps = json!({ "capabilities": { "alwaysMatch": {
        "browserName": "chrome",
        "goog:chromeOptions": {
            "binary": chromium.to_string_lossy(),
            "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                format!("--user-data-dir={}", profile.display()), "--window-size=1100,640"
            ]
        }
    }}});
    let (status, body) = http(port, "POST", "/session", Some(&caps)).expect("new session");
    let v: Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(status, 200, "new session: {v}");
    let d = Driver { port, session: v["value"]["sessionId"].as_str().unwrap().to_string() };

    d.cmd("POST", "/url", Some(json!({ "url": url })));
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
    let png = base64_decode(d.cmd("GET", "/screenshot", None).as_str().unwrap());
    assert_eq!(&png[1..4], b"PNG");
    let shot = if std::env::var_os("FROND_UPDATE_SCREENSHOT").is_some_and(|v| v == "1") {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("screenshot.png")
    } else {
        std::env::temp_dir().join(format!("frond-warp-screenshot-{}.png", std::process::id()))
    };
    std::fs::write(&shot, &png).unwrap();
    eprintln!("screenshot: {}", shot.display());
    let _ = http(port, "DELETE", &format!("/session/{}", d.session), None);
}
