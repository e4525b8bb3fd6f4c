//! Headless-browser testing for frond's pages: Debian's Chromium driven through chromedriver's
//! W3C WebDriver HTTP API (a tiny client over `TcpStream`, loopback only), shared by the tests of
//! `frond-warp serve` and `frond-console`.
//!
//! Without chromium/chromedriver, [`browser`] says why and returns `None` (the test skips;
//! install them with `exporters/warp/tests/install-browser.sh`); under `CI=true` or
//! `FROND_REQUIRE_BROWSER=1` a missing browser fails the test.

#![warn(missing_docs)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

/// Kills a child process that this test started when dropped.
pub struct Guard(pub Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The first of `names` that exists: an absolute path, or a file on `PATH`.
pub fn find(names: &[&str]) -> Option<PathBuf> {
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

/// Whether a missing browser fails the test (`CI=true` or `FROND_REQUIRE_BROWSER=1`).
pub fn browser_required() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
        || std::env::var("FROND_REQUIRE_BROWSER").is_ok_and(|v| v == "1" || v == "true")
}

/// One HTTP/1.1 request to `127.0.0.1:port`; returns status and body.
pub fn http(port: u16, method: &str, path: &str, body: Option<&Value>) -> std::io::Result<(u16, Vec<u8>)> {
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

/// A WebDriver session; dropping it (also when a test fails) closes the browser, then stops
/// chromedriver, so no Chromium outlives the test.
pub struct Driver {
    port: u16,
    session: String,
    _chromedriver: Guard,
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = http(self.port, "DELETE", &format!("/session/{}", self.session), None);
    }
}

impl Driver {
    /// One WebDriver command on the session; its `value`.
    pub fn cmd(&self, method: &str, what: &str, body: Option<Value>) -> Value {
        let path = format!("/session/{}{what}", self.session);
        let (status, bytes) = http(self.port, method, &path, body.as_ref()).expect("webdriver request");
        let v: Value = serde_json::from_slice(&bytes).expect("webdriver JSON");
        assert_eq!(status, 200, "{method} {what}: {v}");
        v["value"].clone()
    }
    /// Runs a synchronous script; its return value.
    pub fn script(&self, src: &str) -> Value {
        self.cmd("POST", "/execute/sync", Some(json!({ "script": src, "args": [] })))
    }
    /// Runs an asynchronous script (it calls `arguments[arguments.length - 1]`); its value.
    pub fn async_script(&self, src: &str) -> Value {
        self.cmd("POST", "/execute/async", Some(json!({ "script": src, "args": [] })))
    }
    /// A screenshot of the window, PNG bytes.
    pub fn screenshot_png(&self) -> Vec<u8> {
        let png = base64_decode(self.cmd("GET", "/screenshot", None).as_str().expect("base64"));
        assert_eq!(&png[1..4], b"PNG");
        png
    }
}

/// Calls `f` every 200 ms until it gives a value; panics naming `what` after `timeout`.
pub fn poll<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// A TCP port free on 127.0.0.1 now.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// Decodes standard base64 (what WebDriver's screenshots are), skipping other bytes.
pub fn base64_decode(s: &str) -> Vec<u8> {
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

/// Chromium and chromedriver, or `None` (after saying why) when they are missing and not
/// required.
pub fn browser() -> Option<(PathBuf, PathBuf)> {
    let chromium = find(&["chromium", "chromium-browser", "/usr/bin/chromium"]);
    let driver = find(&["chromedriver", "/usr/bin/chromedriver"]);
    let (Some(chromium), Some(driver)) = (chromium, driver) else {
        let msg = "chromium and/or chromedriver not found; install them with exporters/warp/tests/install-browser.sh";
        if browser_required() {
            panic!("{msg} (required because CI=true or FROND_REQUIRE_BROWSER=1)");
        }
        println!("SKIPPED browser test: {msg}");
        eprintln!("SKIPPED browser test: {msg}");
        return None;
    };
    Some((chromium, driver))
}

/// Starts chromedriver and a headless Chromium session of `width x height` on `url`.
pub fn start_session(chromium: &Path, driver: &Path, profile: &Path, window: &str, url: &str) -> Driver {
    start_session_with(chromium, driver, profile, window, url, &[])
}

/// [`start_session`] with more Chromium switches (`--host-resolver-rules=...`).
pub fn start_session_with(
    chromium: &Path,
    driver: &Path,
    profile: &Path,
    window: &str,
    url: &str,
    extra: &[&str],
) -> Driver {
    let port = free_port();
    let wd = Command::new(driver)
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start chromedriver");
    let guard = Guard(wd);
    poll("chromedriver", Duration::from_secs(30), || {
        http(port, "GET", "/status", None)
            .ok()
            .and_then(|(_, b)| serde_json::from_slice::<Value>(&b).ok())
            .filter(|v| v["value"]["ready"] == json!(true))
    });
    let mut args: Vec<String> = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        // WebGL on the CPU (SwiftShader): the machines that run the tests have no GPU.
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    args.push(format!("--user-data-dir={}", profile.display()));
    args.push(format!("--window-size={window}"));
    args.extend(extra.iter().map(|a| a.to_string()));
    let caps = json!({ "capabilities": { "alwaysMatch": {
        "browserName": "chrome",
        "goog:chromeOptions": { "binary": chromium.to_string_lossy(), "args": args }
    }}});
    let (status, body) = http(port, "POST", "/session", Some(&caps)).expect("new session");
    let v: Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(status, 200, "new session: {v}");
    let d =
        Driver { port, session: v["value"]["sessionId"].as_str().unwrap().to_string(), _chromedriver: guard };
    d.cmd("POST", "/url", Some(json!({ "url": url })));
    d
}
