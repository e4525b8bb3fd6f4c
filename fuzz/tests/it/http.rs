//! Fuzzes the request-head parser of frond's pages (`frond_web::http::parse_head`), which reads
//! every request the console and `frond-warp serve` receive, from any page the operator's browser
//! visits. A head is refused with a status (400 or 413) or parsed; a parsed one holds at most
//! one `Host`/`Origin`, a body length within the limit, and no header value with a line break.

use frond_fuzz::{Target, fuzz};
use frond_web::http::{MAX_BODY_BYTES, parse_head};

#[test]
fn fuzz_http_request_heads() {
    let seeds: Vec<Vec<u8>> = [
        "GET / HTTP/1.1\r\nHost: 127.0.0.1:8790\r\n\r\n",
        "GET /api/takes?token=abc%20d&x HTTP/1.1\r\nHost: localhost:8790\r\nCookie: frond_token=0123456789abcdef\r\n\r\n",
        "POST /api/record/start HTTP/1.1\r\nHost: [::1]:8790\r\nOrigin: http://[::1]:8790\r\nContent-Length: 17\r\nContent-Type: application/json\r\n\r\n",
        "GET /ws HTTP/1.1\r\nHost: 127.0.0.1:8790\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
        "HEAD /rig.glb HTTP/1.1\r\nHost: 127.0.0.1:8790\r\nAuthorization: Bearer 0123456789abcdef0123\r\n\r\n",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    let dict: Vec<Vec<u8>> = [
        "\r\n",
        "\r\n\r\n",
        "\n",
        "\r",
        "Host: ",
        "Origin: ",
        "Content-Length: ",
        "Transfer-Encoding: chunked",
        "Cookie: ",
        "Authorization: Bearer ",
        "%0d%0a",
        "%",
        "?",
        "&",
        "=",
        "+",
        ":",
        "[",
        "]",
        "\0",
        "\u{7f}",
        "\u{ff}",
        " ",
        "\t",
        "HTTP/1.1",
        "HTTP/1.0",
        "GET ",
        "POST ",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    let report =
        fuzz(Target::new("http-head").seeds(seeds).dict(dict).max_len(4096), |b| match parse_head(b) {
            Ok((req, len)) => {
                assert!(len <= MAX_BODY_BYTES, "body {len}");
                for name in ["host", "origin", "content-length"] {
                    assert!(req.headers.iter().filter(|(n, _)| n == name).count() <= 1, "two {name}");
                }
                for (n, v) in &req.headers {
                    assert!(!v.contains(['\r', '\n']), "{n}: {v:?}");
                    assert_eq!(n, &n.to_ascii_lowercase());
                }
                "ok"
            }
            Err(e) => {
                let status = e.status().expect("a parse error has a status");
                assert!(status == 400 || status == 413, "{status}: {e}");
                assert!(!e.to_string().is_empty());
                "refused"
            }
        });
    report.assert_reaches("ok", 30);
    report.assert_reaches("refused", 100);
}
