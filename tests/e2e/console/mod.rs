//! `frond-console` on a real daemon (issue 19): the page's 3D scene follows the live poses
//! (bones' world positions read back from the page against forward kinematics of the poses the
//! page received, computed here from the rig's heights and the protocol's rotation convention),
//! the recording controls leave a take on disk, and the access rules refuse what they must.

mod access;
mod calibration;
mod camera;
mod hostile;
mod kinematics;
mod meadow;
mod view;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::Duration;

use frond_e2e::{Daemon, Proc, bin};
use frond_webdriver::Driver;

/// Starts `frond-console ARGS` on `daemon` and returns it with its URL and the whole first line.
pub(super) fn start_console(daemon: &Daemon, args: &[&str]) -> (Proc, String, String) {
    start_console_on(&daemon.socket_dir, &daemon.takes_dir, args)
}

/// Starts `frond-console ARGS` on the daemon of `socket_dir`, as [`start_console`].
pub(super) fn start_console_on(
    socket_dir: &std::path::Path,
    takes_dir: &std::path::Path,
    args: &[&str],
) -> (Proc, String, String) {
    let mut child = Command::new(bin("frond-console"))
        .arg("--socket-dir")
        .arg(socket_dir)
        .arg("--takes-dir")
        .arg(takes_dir)
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
pub(super) fn request(
    addr: &str,
    method: &str,
    path: &str,
    headers: &str,
    body: &str,
) -> (u16, String, String) {
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

/// Saves a screenshot: over `exporters/console/NAME` with `FROND_UPDATE_SCREENSHOT=1` (the
/// README's picture), else into the temporary directory.
pub(super) fn save_screenshot(d: &Driver, name: &str) {
    let png = d.screenshot_png();
    let shot = if std::env::var_os("FROND_UPDATE_SCREENSHOT").is_some_and(|v| v == "1") {
        frond_e2e::repo_root().join("exporters/console").join(name)
    } else {
        std::env::temp_dir().join(format!("frond-console-{}-{name}", std::process::id()))
    };
    std::fs::write(&shot, &png).unwrap();
    eprintln!("screenshot: {}", shot.display());
}

/// `GET path` from the console at `url`, the body.
pub(super) fn request_json(url: &str, path: &str) -> String {
    let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
    let (s, _, body) = request(&addr, "GET", path, &format!("Host: {addr}\r\n"), "");
    assert_eq!(s, 200, "{path}: {body}");
    body
}
