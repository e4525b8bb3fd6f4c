//! Who may use the console: beyond loopback every request needs the token; on loopback another
//! host name or another site's origin is refused.

use std::time::Duration;

use frond_e2e::{Daemon, wait_for};
use serde_json::Value;

use super::{request, start_console};

#[test]
fn beyond_loopback_every_request_needs_the_token_and_control_needs_the_origin() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let token = "tok-0123456789abcdef";
    std::fs::write(dir.path().join("token"), format!("{token}\n")).unwrap();
    let token_file = dir.path().join("token");
    // A secret: frond-console refuses a token file its group or other users may read.
    std::fs::set_permissions(&token_file, std::os::unix::fs::PermissionsExt::from_mode(0o600)).unwrap();
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
