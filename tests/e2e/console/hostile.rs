//! The console against a hostile browser and hostile local clients (issue 42, section 1), on the
//! real binaries: a crafted link cannot split a response, a rebinding name is not this server,
//! clients that trickle their requests cannot lock the operator out, and however many pages poll
//! status, the console holds at most two of the daemon's control connections.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use frond_e2e::Daemon;
use frond_protocol::{CONTROL_SOCKET, POSES_SOCKET};

use super::{request, start_console, start_console_on};

/// A console on loopback for `daemon`: the process, `ADDR` and its `Host:` line.
fn loopback_console(daemon: &Daemon) -> (frond_e2e::Proc, String, String) {
    let (console, url, _) = start_console(daemon, &["--listen", "127.0.0.1:0"]);
    let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
    let host = format!("Host: {addr}\r\n");
    (console, addr, host)
}

#[test]
fn a_crafted_link_cannot_split_the_answer_or_set_a_cookie() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let (_console, addr, host) = loopback_console(&daemon);
    // A link an attacker sends the operator: its query would end the head and add its own
    // header (and with a body, its own page on the console's origin).
    let link = "/?token=x%0d%0aSet-Cookie:%20frond_token=evil%0d%0aContent-Length:%200%0d%0a%0d%0a<script>alert(1)</script>";
    let (s, head, body) = request(&addr, "GET", link, &host, "");
    assert_eq!(s, 200, "{head}");
    assert!(
        !head.to_ascii_lowercase().contains("set-cookie"),
        "no token is configured, so no cookie: {head}"
    );
    assert!(!body.contains("<script>alert(1)</script>"), "{body}");
    // Every line of the head is one of the server's own.
    for line in head.lines().skip(1) {
        let name = line.split(':').next().unwrap();
        assert!(
            [
                "Content-Type",
                "Content-Length",
                "X-Content-Type-Options",
                "Connection",
                "Cache-Control",
                "X-Frame-Options",
                "Content-Security-Policy",
                "Referrer-Policy",
            ]
            .contains(&name),
            "{line:?} in {head}"
        );
    }
}

#[test]
fn a_rebinding_name_and_a_second_host_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let (_console, addr, host) = loopback_console(&daemon);
    let port = addr.rsplit(':').next().unwrap();
    for name in ["127.0.0.1.evil.example", "127.evil.example", "127.0.0.1.nip.io", "localhost.evil.example"] {
        let (s, _, body) = request(&addr, "GET", "/api/hello", &format!("Host: {name}:{port}\r\n"), "");
        assert_eq!(s, 403, "{name}: {body}");
    }
    for ok in [format!("localhost:{port}"), format!("127.0.0.1:{port}")] {
        let (s, _, body) = request(&addr, "GET", "/api/hello", &format!("Host: {ok}\r\n"), "");
        assert_eq!(s, 200, "{ok}: {body}");
    }
    // RFC 9112, section 3.2: two Hosts are a bad request (a check may read one, a proxy the other).
    let (s, _, body) = request(&addr, "GET", "/api/hello", &format!("{host}Host: evil.example\r\n"), "");
    assert_eq!(s, 400, "{body}");
    let origins = format!("{host}Origin: http://{addr}\r\nOrigin: http://evil.example\r\n");
    let (s, _, body) = request(&addr, "POST", "/api/record/stop", &origins, "");
    assert_eq!(s, 400, "{body}");
}

/// Opens `n` connections that send a request's first bytes and then a byte every `gap`, until
/// the server closes them or `stop` is set.
fn tricklers(
    addr: &str,
    n: usize,
    gap: Duration,
    stop: &Arc<AtomicUsize>,
) -> Vec<std::thread::JoinHandle<()>> {
    (0..n)
        .map(|_| {
            let (addr, stop) = (addr.to_string(), Arc::clone(stop));
            std::thread::spawn(move || {
                let Ok(mut s) = TcpStream::connect(&addr) else { return };
                if s.write_all(format!("GET /api/hello HTTP/1.1\r\nHost: {addr}\r\n").as_bytes()).is_err() {
                    return;
                }
                while stop.load(Ordering::Relaxed) == 0 {
                    std::thread::sleep(gap);
                    if s.write_all(b"X").is_err() {
                        return;
                    }
                }
            })
        })
        .collect()
}

#[test]
fn clients_that_trickle_their_requests_never_lock_the_operator_out() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let (_console, addr, host) = loopback_console(&daemon);
    let stop = Arc::new(AtomicUsize::new(0));
    // More slow clients than the console serves at once (64), each well within a per-read
    // timeout.
    let slow = tricklers(&addr, 100, Duration::from_millis(200), &stop);
    std::thread::sleep(Duration::from_millis(500));
    for _ in 0..5 {
        let (s, _, body) = request(&addr, "GET", "/api/hello", &host, "");
        assert_eq!(s, 200, "the operator is served while slow clients hold connections: {body}");
    }
    let (s, _, body) = request(&addr, "GET", "/api/status", &host, "");
    assert_eq!(s, 200, "{body}");
    let status: serde_json::Value = serde_json::from_str(&body).unwrap();
    let gate = &status["console"]["connections"];
    assert!(gate["evicted"].as_u64().unwrap() >= 30, "{gate}");
    stop.store(1, Ordering::Relaxed);
    for t in slow {
        t.join().unwrap();
    }
}

#[test]
fn a_request_trickled_past_the_deadline_is_answered_408() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let (_console, addr, _) = loopback_console(&daemon);
    let mut s = TcpStream::connect(&addr).unwrap();
    s.write_all(format!("GET /api/hello HTTP/1.1\r\nHost: {addr}\r\nX: ").as_bytes()).unwrap();
    // A byte a second: every read is quick; the whole request never arrives. The console's
    // deadline for a whole request is 10 s.
    let start = Instant::now();
    let mut answer = Vec::new();
    s.set_read_timeout(Some(Duration::from_millis(900))).unwrap();
    while start.elapsed() < Duration::from_secs(30) {
        if s.write_all(b"a").is_err() {
            break;
        }
        match s.read_to_end(&mut answer) {
            Ok(_) => break,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(_) => break,
        }
    }
    let text = String::from_utf8_lossy(&answer);
    assert!(text.starts_with("HTTP/1.1 408 "), "after {:?}: {text:?}", start.elapsed());
}

/// A socket directory for the console in front of `daemon`'s: the pose socket linked, the
/// control socket a proxy that counts the connections made to it.
fn counting_socket_dir(daemon: &Daemon, dir: &Path) -> Arc<AtomicUsize> {
    std::fs::create_dir_all(dir).unwrap();
    std::os::unix::fs::symlink(daemon.socket_dir.join(POSES_SOCKET), dir.join(POSES_SOCKET)).unwrap();
    let listener = UnixListener::bind(dir.join(CONTROL_SOCKET)).unwrap();
    let count = Arc::new(AtomicUsize::new(0));
    let (counted, real) = (Arc::clone(&count), daemon.socket_dir.join(CONTROL_SOCKET));
    std::thread::spawn(move || {
        for conn in listener.incoming() {
            let Ok(conn) = conn else { return };
            counted.fetch_add(1, Ordering::SeqCst);
            let Ok(upstream) = UnixStream::connect(&real) else { continue };
            for (mut from, mut to) in
                [(conn.try_clone().unwrap(), upstream.try_clone().unwrap()), (upstream, conn)]
            {
                std::thread::spawn(move || {
                    let _ = std::io::copy(&mut from, &mut to);
                    let _ = to.shutdown(std::net::Shutdown::Write);
                });
            }
        }
    });
    count
}

#[test]
fn pages_polling_status_share_one_control_connection() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let front = dir.path().join("front");
    let connections = counting_socket_dir(&daemon, &front);
    let (_console, url, _) =
        start_console_on(&front, &daemon.takes_dir, &["--listen", "127.0.0.1:0", "--no-warp"]);
    let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
    let host = format!("Host: {addr}\r\n");
    // Twenty pages polling together, five times each.
    let pages: Vec<_> = (0..20)
        .map(|_| {
            let (addr, host) = (addr.clone(), host.clone());
            std::thread::spawn(move || {
                for _ in 0..5 {
                    let (s, _, body) = request(&addr, "GET", "/api/status", &host, "");
                    assert_eq!(s, 200, "{body}");
                    assert!(body.contains("\"daemon\":{"), "the daemon's report: {body}");
                }
            })
        })
        .collect();
    for p in pages {
        p.join().unwrap();
    }
    // One connection for status (opened anew only after 20 s idle); each read was the daemon's.
    assert_eq!(connections.load(Ordering::SeqCst), 1, "100 status reads, one control connection");
    // `frond` finds the daemon's control socket free.
    daemon.frond_ok(&["status"]);
}

/// The attacker's page: every way a page can reach the console at `console` (`127.0.0.1:P`)
/// from another origin, each outcome put in `window.results` (`"sent"` when the browser let
/// the request go out; what it could read, if anything), `window.done` when all are tried.
fn attacker_page(console: &str, console_port: u16) -> String {
    format!(
        r#"<!doctype html><html><body><h1>cat pictures</h1>
<iframe name="sink" style="display:none"></iframe>
<iframe id="framed" src="http://{console}/" style="width:10px;height:10px"></iframe>
<img id="glb" src="http://{console}/rig.glb" style="display:none">
<form id="f" method="POST" action="http://{console}/api/record/start" target="sink" enctype="text/plain">
<input name='{{"name":"evil-form","x":"' value='"}}'></form>
<script>
window.results = {{}};
const tries = [];
const at = (k, p) => tries.push(p.then(v => {{ window.results[k] = v; }}, e => {{ window.results[k] = 'error: ' + e; }}));
// A simple POST (no preflight): the browser sends it with this page's Origin.
at('fetch-record', fetch('http://{console}/api/record/start', {{method: 'POST', mode: 'no-cors', body: '{{"name":"evil-fetch"}}'}}).then(r => 'sent'));
at('fetch-mark', fetch('http://{console}/api/mark', {{method: 'POST', mode: 'no-cors', body: '{{"label":"evil"}}'}}).then(r => 'sent'));
at('fetch-rig', fetch('http://{console}/api/rig', {{method: 'POST', mode: 'no-cors', body: '{{"rig":"flower"}}'}}).then(r => 'sent'));
// A read across origins: CORS keeps the answer from the page; the console refuses it anyway.
at('fetch-status', fetch('http://{console}/api/status').then(r => r.text()));
// Through the rebinding name: same port, Host evil.test.
at('rebind-record', fetch('http://evil.test:{console_port}/api/record/start', {{method: 'POST', mode: 'no-cors', body: '{{"name":"evil-rebind"}}'}}).then(r => 'sent'));
// The pose WebSocket.
at('websocket', new Promise(res => {{
  const ws = new WebSocket('ws://{console}/ws');
  ws.onopen = () => res('open');
  ws.onerror = () => res('refused');
}}));
// A GET without Origin: an image of the rig's GLB and a script of the takes list (Fetch
// Metadata marks them cross-site), and the console framed (clickjacking).
at('img', new Promise(res => {{ const i = document.getElementById('glb'); i.onerror = () => res('refused'); i.onload = () => res('loaded'); }}));
at('script', new Promise(res => {{ const s = document.createElement('script'); s.src = 'http://{console}/api/takes'; s.onerror = () => res('refused'); s.onload = () => res('loaded'); document.body.appendChild(s); }}));
// A form POST (a navigation, so no CORS at all).
document.getElementById('f').submit();
at('form', new Promise(res => setTimeout(() => res('sent'), 1500)));
Promise.all(tries).then(() => {{ window.done = true; }});
</script></body></html>"#
    )
}

/// Serves `page` to every GET on `listener` (the attacker's site).
fn serve_page(listener: std::net::TcpListener, page: String) {
    std::thread::spawn(move || {
        for conn in listener.incoming() {
            let Ok(mut c) = conn else { return };
            let mut buf = [0u8; 4096];
            let _ = c.set_read_timeout(Some(Duration::from_secs(5)));
            let _ = c.read(&mut buf);
            let _ = write!(
                c,
                "HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{page}",
                page.len()
            );
        }
    });
}

/// A browser on `page`, another site's (served at `evil.test`, which resolves to this machine
/// as a rebinding DNS server would make it), once the page has set `window.done`.
pub(super) fn attack(
    chromium: &Path,
    driver: &Path,
    profile: &Path,
    page: String,
) -> frond_webdriver::Driver {
    let evil = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let evil_port = evil.local_addr().unwrap().port();
    serve_page(evil, page);
    let d = frond_webdriver::start_session_with(
        chromium,
        driver,
        profile,
        "800,600",
        &format!("http://evil.test:{evil_port}/"),
        &["--host-resolver-rules=MAP evil.test 127.0.0.1"],
    );
    frond_webdriver::poll("the attacker's page to try everything", Duration::from_secs(60), || {
        (d.script("return window.done === true") == serde_json::json!(true)).then_some(())
    });
    d
}

#[test]
fn another_sites_page_in_a_real_browser_changes_nothing() {
    let Some((chromium, driver)) = frond_webdriver::browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let (_console, addr, host) = loopback_console(&daemon);
    let port: u16 = addr.rsplit(':').next().unwrap().parse().unwrap();
    let rig_before = daemon.status().rig_name;
    let d = attack(&chromium, &driver, &dir.path().join("profile"), attacker_page(&addr, port));
    let results = d.script("return window.results");
    eprintln!("attacker's page: {results}");
    assert_eq!(results["websocket"], "refused", "{results}");
    assert!(!results["fetch-status"].as_str().unwrap_or("").contains("\"daemon\""), "{results}");
    // The rebinding name, navigated to: the console's page is not served under it.
    d.cmd("POST", "/url", Some(serde_json::json!({ "url": format!("http://evil.test:{port}/") })));
    let text = d.script("return document.body.innerText").as_str().unwrap_or("").to_string();
    assert!(text.contains("is not this server"), "{text}");
    // A crafted link, followed: no cookie on the console's origin, no injected script.
    let link = format!(
        "http://{addr}/?token=x%0d%0aSet-Cookie:%20frond_token=evil%0d%0a%0d%0a%3Cscript%3Ewindow.pwned=1%3C/script%3E"
    );
    d.cmd("POST", "/url", Some(serde_json::json!({ "url": link })));
    assert_eq!(d.cmd("GET", "/cookie", None), serde_json::json!([]), "no cookie was set");
    assert_ne!(d.script("return window.pwned === 1"), serde_json::json!(true));
    // The daemon: no take, no recording, the same rig.
    let status = daemon.status();
    assert!(status.recording.is_none(), "{:?}", status.recording);
    assert_eq!(status.rig_name, rig_before);
    let takes: Vec<_> =
        std::fs::read_dir(&daemon.takes_dir).map(|r| r.flatten().collect()).unwrap_or_default();
    assert!(takes.is_empty(), "{takes:?}");
    // The console says so: every attempt was refused and counted.
    let (s, _, body) = request(&addr, "GET", "/api/status", &host, "");
    assert_eq!(s, 200, "{body}");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    // fetch x3, rebinding, WebSocket, form, the frame, the image, the script, the rebinding
    // page navigated to.
    assert!(v["console"]["refused"].as_u64().unwrap() >= 10, "{}", v["console"]);
    // The control: the console's own page, in the same browser, does start a recording (so the
    // requests above reached a console that would have acted on them).
    d.cmd("POST", "/url", Some(serde_json::json!({ "url": format!("http://{addr}/") })));
    let answer = d.async_script(
        "const done = arguments[arguments.length - 1];
         fetch('/api/record/start', {method: 'POST', headers: {'Content-Type': 'application/json'}, body: '{\"name\":\"own-page\"}'})
           .then(r => done(r.status), e => done('error: ' + e));",
    );
    assert_eq!(answer, serde_json::json!(200), "the console's own page may act");
    assert!(frond_e2e::wait_for(Duration::from_secs(5), || daemon.status().recording.is_some()));
    daemon.frond_ok(&["record", "stop"]);
}
