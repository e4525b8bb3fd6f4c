//! The console's HTTP and WebSocket server against hostile and mistaken requests, over a real
//! socket (no daemon: nothing here needs one). Expected answers come from the RFCs: 9110 (HTTP
//! semantics), 9112 (HTTP/1.1 framing) and 6455 (WebSocket).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use frond_console::access::Access;
use frond_console::server::{Config, Console};
use frond_formats::take::{TakeRecord, encode_file_start, encode_record};
use frond_motion::take::{TakeFrame, TakeHeader};
use frond_motion::{HandSample, JOINTS, PoseFrame};
use frond_protocol::ElementId;

/// A console on a free loopback port, its directories, and the port's address.
struct Served {
    addr: SocketAddr,
    _dirs: tempfile::TempDir,
}

impl Served {
    /// A console whose takes directory holds `takes` (name, frames one `step_s` apart).
    fn start(takes: &[(&str, usize, f64)]) -> Served {
        let dirs = tempfile::tempdir().unwrap();
        let takes_dir = dirs.path().join("takes");
        std::fs::create_dir_all(&takes_dir).unwrap();
        for (name, frames, step_s) in takes {
            write_take(&takes_dir, name, *frames, *step_s);
        }
        Served::serve(dirs, None)
    }

    /// A console whose scratch directory holds `files` (name, text) and whose takes directory
    /// holds one-second takes (name, the rig their header names), started with `--rig
    /// own_rig` if given; `{dir}` in a rig name stands for the scratch directory.
    fn start_on(files: &[(&str, &str)], takes: &[(&str, &str)], own_rig: Option<&str>) -> Served {
        let dirs = tempfile::tempdir().unwrap();
        let at = |name: &str| name.replace("{dir}", dirs.path().to_str().unwrap());
        for (name, text) in files {
            std::fs::write(dirs.path().join(name), text).unwrap();
        }
        let takes_dir = dirs.path().join("takes");
        std::fs::create_dir_all(&takes_dir).unwrap();
        for (name, rig) in takes {
            write_take_on(&takes_dir, name, &at(rig), 30, 1.0 / 30.0);
        }
        let own = own_rig.map(|r| Arc::new(frond_console::scene::load(&at(r)).unwrap()));
        Served::serve(dirs, own)
    }

    fn serve(dirs: tempfile::TempDir, rig: Option<Arc<frond_console::scene::RigScene>>) -> Served {
        let (socket_dir, takes_dir) = (dirs.path().join("sockets"), dirs.path().join("takes"));
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let console = Console::start(Config {
            socket_dir,
            takes_dir,
            access: Access { loopback: true, port: addr.port(), token: None },
            rig,
            display_hz: 30,
            warp: false,
        })
        .unwrap();
        let me = Arc::clone(&console);
        std::thread::spawn(move || me.serve(listener));
        Served { addr, _dirs: dirs }
    }

    /// Sends `head_lines` (request line and headers, without the blank line) and `body`; the
    /// whole answer as text, read until the server closes (or until a 101's head).
    fn exchange(&self, head_lines: &str, body: &[u8]) -> String {
        let mut s = TcpStream::connect(self.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        let origin = format!("http://{}", self.addr);
        let head = format!("{head_lines}\r\nHost: {}\r\nOrigin: {origin}\r\n\r\n", self.addr);
        s.write_all(head.as_bytes()).unwrap();
        s.write_all(body).unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 8192];
        loop {
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) => panic!("reading the answer to {head_lines:?}: {e} (so far {got:?})"),
            }
            // A WebSocket stays open: its head is the whole answer here.
            if got.starts_with(b"HTTP/1.1 101") && got.windows(4).any(|w| w == b"\r\n\r\n") {
                break;
            }
        }
        String::from_utf8_lossy(&got).into_owned()
    }
}

/// The status of an answer.
fn status(answer: &str) -> u16 {
    answer.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or_else(|| panic!("no status: {answer:?}"))
}

/// A header's value (the first of that name, case-insensitive).
fn header<'a>(answer: &'a str, name: &str) -> Option<&'a str> {
    let head = answer.split("\r\n\r\n").next().unwrap();
    head.lines().skip(1).find_map(|l| {
        let (n, v) = l.split_once(':')?;
        n.eq_ignore_ascii_case(name).then(|| v.trim())
    })
}

/// The body of an answer (after the head's blank line).
fn body(answer: &str) -> &str {
    answer.split_once("\r\n\r\n").map_or("", |(_, b)| b)
}

/// Writes take `name` into `dir`: a header on the grass rig and `frames` main-skeleton frames
/// `step_s` seconds apart, then the End record.
fn write_take(dir: &Path, name: &str, frames: usize, step_s: f64) {
    write_take_on(dir, name, "grass", frames, step_s)
}

/// [`write_take`] with a header that names rig `rig`.
fn write_take_on(dir: &Path, name: &str, rig: &str, frames: usize, step_s: f64) {
    write_take_of(dir, name, rig, 0, frames, step_s)
}

/// [`write_take_on`] with every frame on element `element` (a take of `frond record layer`
/// holds only its layer's frames).
fn write_take_of(dir: &Path, name: &str, rig: &str, element: u16, frames: usize, step_s: f64) {
    let mut out = Vec::new();
    encode_file_start(&mut out);
    encode_record(&TakeRecord::Header(TakeHeader::offline(name, rig, 1000)), &mut out);
    for i in 0..frames {
        let t = i as f64 * step_s;
        let frame = TakeFrame {
            seq: i as u64,
            device_time_us: (t * 1e6) as u64,
            host_ns: (t * 1e9) as u64,
            flags: 0,
            element: ElementId::new(element),
            pose: PoseFrame { t, joints_deg: [[(i % 30) as f32, 0.0, 0.0]; JOINTS] },
            hand: HandSample { t, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3] },
        };
        encode_record(&TakeRecord::Frame(frame), &mut out);
    }
    encode_record(&TakeRecord::End { frames: frames as u64 }, &mut out);
    std::fs::write(dir.join(format!("{name}.take")), out).unwrap();
}

#[test]
fn differing_content_lengths_are_refused_not_guessed() {
    // RFC 9112, section 6.3 (3): differing Content-Length values are an unrecoverable framing
    // error; a server MUST answer 400. The old console took the first (2 bytes, `{}`) and
    // cancelled the calibration (200).
    let c = Served::start(&[]);
    let a = c.exchange(
        "POST /api/calibrate/cancel HTTP/1.1\r\nContent-Length: 2\r\nContent-Length: 10",
        b"{}12345678",
    );
    assert_eq!(status(&a), 400, "{a}");
    assert!(body(&a).contains("Content-Length"), "{a}");
    // Transfer-Encoding beside Content-Length: also 400 (section 6.1: a server may reject it;
    // this one takes no chunked bodies at all).
    let a = c.exchange(
        "POST /api/calibrate/cancel HTTP/1.1\r\nContent-Length: 2\r\nTransfer-Encoding: chunked",
        b"{}",
    );
    assert_eq!(status(&a), 400, "{a}");
    // One Content-Length is taken.
    let a = c.exchange("POST /api/calibrate/cancel HTTP/1.1\r\nContent-Length: 2", b"{}");
    assert_eq!(status(&a), 200, "{a}");
}

#[test]
fn allow_lists_what_the_path_takes() {
    // RFC 9110, section 15.5.6: a 405 MUST carry Allow with the target's methods.
    let c = Served::start(&[]);
    for (request, allow) in [
        ("OPTIONS /api/record/start HTTP/1.1", "POST"),
        ("GET /api/record/start HTTP/1.1", "POST"),
        ("PUT /api/calibrate/start HTTP/1.1", "POST"),
        ("DELETE /api/takes/repair HTTP/1.1", "POST"),
        ("OPTIONS /api/status HTTP/1.1", "GET, HEAD"),
        ("POST /rig.glb HTTP/1.1\r\nContent-Length: 0", "GET, HEAD"),
        ("POST /api/takes/t1.glb HTTP/1.1\r\nContent-Length: 0", "GET, HEAD"),
        ("POST /ws HTTP/1.1\r\nContent-Length: 0", "GET, HEAD"),
    ] {
        let a = c.exchange(request, b"");
        assert_eq!(status(&a), 405, "{request}: {a}");
        assert_eq!(header(&a, "allow"), Some(allow), "{request}: {a}");
    }
    // Nothing there is 404 whatever the method.
    for request in ["OPTIONS /nowhere HTTP/1.1", "POST /nowhere HTTP/1.1\r\nContent-Length: 0"] {
        let a = c.exchange(request, b"");
        assert_eq!(status(&a), 404, "{request}: {a}");
    }
}

#[test]
fn head_answers_carry_gets_headers_and_no_body() {
    // RFC 9110, section 9.3.2: HEAD is GET without the content; Content-Length may say GET's.
    let c = Served::start(&[]);
    // A WebSocket's path too: GET without the upgrade is 426, and HEAD the same head.
    for path in ["/", "/console.js", "/api/rigs", "/api/nowhere", "/ws", "/ws/warp"] {
        let get = c.exchange(&format!("GET {path} HTTP/1.1"), b"");
        let head = c.exchange(&format!("HEAD {path} HTTP/1.1"), b"");
        assert_eq!(status(&head), status(&get), "{path}");
        assert_eq!(body(&head), "", "HEAD {path} sent a body: {head}");
        assert!(head.ends_with("\r\n\r\n"), "{head}");
        assert_eq!(header(&head, "content-length"), Some(body(&get).len().to_string().as_str()), "{path}");
        assert_eq!(header(&head, "content-type"), header(&get, "content-type"), "{path}");
        assert_eq!(header(&head, "upgrade"), header(&get, "upgrade"), "{path}");
    }
    let head = c.exchange("HEAD /ws HTTP/1.1", b"");
    assert_eq!((status(&head), header(&head, "upgrade")), (426, Some("websocket")), "{head}");
}

/// The grass rig's file renamed `name` (its `name = "grass"` line replaced).
fn rig_named(name: &str) -> String {
    let grass = frond_formats::rig_files::EMBEDDED_RIGS[0].1;
    assert!(grass.contains("\nname = \"grass\"\n"));
    grass.replacen("\nname = \"grass\"\n", &format!("\nname = \"{name}\"\n"), 1)
}

#[test]
fn a_takes_rig_name_is_never_opened_as_a_path() {
    // A take keeps its rig's name; a take file (or anyone who can write one) naming a path
    // there must not make the console read that file. The old console opened it: the rig file
    // below baked (200), and /dev/zero was read as far as the rig loader's checks.
    let files = [("secret.toml", rig_named("secret"))];
    let files: Vec<(&str, &str)> = files.iter().map(|(n, t)| (*n, t.as_str())).collect();
    let takes = [("by_path", "{dir}/secret.toml"), ("by_name", "secret"), ("device", "/dev/zero")];
    let c = Served::start_on(&files, &takes, None);
    for (take, rig) in [("by_path", "/secret.toml"), ("by_name", "secret"), ("device", "/dev/zero")] {
        let a = c.exchange(&format!("GET /api/takes/{take}.glb HTTP/1.1"), b"");
        assert_eq!(status(&a), 409, "{take}: {a}");
        let answer: serde_json::Value = serde_json::from_str(body(&a)).unwrap();
        let text = answer["error"].as_str().unwrap();
        assert!(text.starts_with(&format!("take \"{take}\" was recorded on rig \"")), "{text}");
        assert!(text.contains(rig) && text.contains("not an embedded rig (grass, flower, shrub)"), "{text}");
        assert!(text.contains("start frond-console with --rig FILE"), "{text}");
    }
    // A take on an embedded rig bakes as before.
    let c = Served::start_on(&files, &[("on_grass", "grass")], None);
    let a = c.exchange("GET /api/takes/on_grass.glb HTTP/1.1", b"");
    assert_eq!(status(&a), 200, "{a}");
    assert!(body(&a).contains(r#""rig":"grass""#), "the GLB's extras name the rig it was baked on");

    // A console started with --rig FILE bakes the takes recorded on a rig that is not embedded
    // on that rig; one on an embedded rig still on its own.
    let takes = [("by_name", "secret"), ("on_grass", "grass")];
    let c = Served::start_on(&files, &takes, Some("{dir}/secret.toml"));
    for (take, baked_on) in [("by_name", "secret"), ("on_grass", "grass")] {
        let a = c.exchange(&format!("GET /api/takes/{take}.glb HTTP/1.1"), b"");
        assert_eq!(status(&a), 200, "{take}: {a}");
        assert!(body(&a).contains(&format!(r#""rig":"{baked_on}""#)), "{take} baked on {baked_on}");
    }
}

#[test]
fn websocket_upgrades_are_checked_as_rfc_6455_says() {
    let c = Served::start(&[]);
    let upgrade = |version: &str, key: &str| {
        c.exchange(
            &format!(
                "GET /ws HTTP/1.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
                 Sec-WebSocket-Version: {version}\r\nSec-WebSocket-Key: {key}"
            ),
            b"",
        )
    };
    // Section 4.2.2 (4): a version the server does not speak: 426 and the versions it does.
    let a = upgrade("99", "dGhlIHNhbXBsZSBub25jZQ==");
    assert_eq!(status(&a), 426, "{a}");
    assert_eq!(header(&a, "sec-websocket-version"), Some("13"), "{a}");
    assert!(body(&a).contains("99"), "{a}");
    // Section 4.1: the key is base64 of 16 random bytes; anything else is a bad request.
    for key in ["x", "AAAAAAAAAAAAAAAAAAAA", "AAAAAAAAAAAAAAAAAAAAAAA="] {
        let a = upgrade("13", key);
        assert_eq!(status(&a), 400, "{key}: {a}");
        assert!(body(&a).contains("Sec-WebSocket-Key"), "{a}");
    }
    // The RFC's own example (section 1.3) is accepted, with its accept key.
    let a = upgrade("13", "dGhlIHNhbXBsZSBub25jZQ==");
    assert_eq!(status(&a), 101, "{a}");
    assert_eq!(header(&a, "sec-websocket-accept"), Some("s3pPLMBiTxaQ9kYGzzhZRbK+xOo="), "{a}");
}

#[test]
fn a_bad_calibration_body_is_a_bad_request_not_a_conflict() {
    // RFC 9110: 400 is a request the client must change; 409 a conflict with the state.
    let c = Served::start(&[]);
    for body_text in [
        r#"{"user":"ann","seconds_per_step":0}"#,
        r#"{"user":"ann","seconds_per_step":1000}"#,
        r#"{"user":"ann","seconds_per_step":"fast"}"#,
    ] {
        let a = c.exchange(
            &format!("POST /api/calibrate/start HTTP/1.1\r\nContent-Length: {}", body_text.len()),
            body_text.as_bytes(),
        );
        assert_eq!(status(&a), 400, "{body_text}: {a}");
        assert!(body(&a).contains("seconds_per_step"), "{a}");
    }
    // A step with no calibration running is a conflict with the state.
    let a = c.exchange("POST /api/calibrate/step HTTP/1.1\r\nContent-Length: 0", b"");
    assert_eq!(status(&a), 409, "{a}");
}

#[test]
fn field_errors_name_the_json_keys_not_command_line_options() {
    let c = Served::start(&[("t", 60, 1.0 / 30.0)]);
    for (body_text, key) in [
        (r#"{"take":"t","cell_m":-1}"#, "cell_m"),
        (r#"{"take":"t","cell_m":0}"#, "cell_m"),
        (r#"{"take":"t","rows":0}"#, "rows"),
    ] {
        let a = c.exchange(
            &format!("POST /api/field/start HTTP/1.1\r\nContent-Length: {}", body_text.len()),
            body_text.as_bytes(),
        );
        assert_eq!(status(&a), 400, "{body_text}: {a}");
        assert!(body(&a).contains(key), "{body_text}: {a}");
        assert!(!body(&a).contains("--"), "names a command-line option: {a}");
    }
}

#[test]
fn a_take_too_long_to_bake_is_the_users_problem_said_in_time() {
    // 36,100 frames 1 s apart (each step interpolated: at most 1 s): 36,099 s = 10 h 1 min 39 s,
    // 1,082,971 keys at 30 FPS, past frond-gltf's 1,080,000 (10 h at 30 FPS).
    let c = Served::start(&[("long", 36_100, 1.0)]);
    let a = c.exchange("GET /api/takes/long.glb HTTP/1.1", b"");
    assert_eq!(status(&a), 413, "{a}");
    let text = body(&a);
    assert!(text.contains("10 h 1 min 39 s"), "how long the take is: {text}");
    assert!(text.contains("at most 10 h "), "the limit: {text}");
    assert!(!text.contains("--force"), "a command-line option means nothing here: {text}");
}

#[test]
fn the_takes_index_reads_a_take_again_only_when_its_file_changed() {
    use std::os::unix::fs::FileExt;
    let dir = tempfile::tempdir().unwrap();
    write_take(dir.path(), "a", 10, 0.1);
    let index = frond_console::takes::TakeIndex::new(dir.path().to_path_buf());
    let listed = index.list();
    assert_eq!(listed["takes"][0]["frames"], 10, "{listed}");
    // The same bytes' length, inode and modification time but garbage inside: a listing that
    // read the file would call it corrupt; the index does not read it.
    let path = dir.path().join("a.take");
    let mtime = std::fs::metadata(&path).unwrap().modified().unwrap();
    let len = std::fs::metadata(&path).unwrap().len() as usize;
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.write_all_at(&vec![0xAB; len], 0).unwrap();
    f.set_modified(mtime).unwrap();
    for _ in 0..3 {
        let again = index.list();
        assert_eq!(again["takes"][0]["frames"], 10, "{again}");
        assert_ne!(again["takes"][0]["state"], "corrupt", "{again}");
    }
    // A changed file is read again at its next listing (a repair, say)...
    f.set_modified(mtime + Duration::from_secs(5)).unwrap();
    let changed = index.list();
    assert_eq!(changed["takes"][0]["state"], "corrupt", "{changed}");
    // ...but one that only grows (a take being recorded) at most once a second.
    write_take(dir.path(), "g", 10, 0.1);
    assert_eq!(index.list()["takes"][1]["frames"], 10);
    let g = std::fs::OpenOptions::new().append(true).open(dir.path().join("g.take")).unwrap();
    std::io::Write::write_all(&mut &g, &[0u8; 7]).unwrap();
    let grown = index.list();
    assert_eq!(grown["takes"][1]["frames"], 10, "{grown}");
    assert_eq!(grown["takes"][1]["size_bytes"], std::fs::metadata(dir.path().join("g.take")).unwrap().len());
    assert_ne!(grown["takes"][1]["state"], "torn", "the last summary until a second has passed: {grown}");
    std::thread::sleep(frond_console::takes::RESCAN_EVERY);
    assert_eq!(index.list()["takes"][1]["state"], "torn");
    std::fs::remove_file(dir.path().join("g.take")).unwrap();
    // A take that goes leaves the index; a new one joins it.
    std::fs::remove_file(&path).unwrap();
    write_take(dir.path(), "b", 3, 0.1);
    let now = index.list();
    assert_eq!(now["takes"].as_array().unwrap().len(), 1, "{now}");
    assert_eq!(now["takes"][0]["name"], "b");
    assert_eq!(now["takes"][0]["frames"], 3);
}

#[test]
fn a_layer_take_lists_the_frames_and_time_of_its_layer() {
    // A take of `frond record layer` holds only its layer's frames: here 25 frames of element 2,
    // 0.1 s apart (2.4 s from the first to the last), beside a plant take of 10.
    let dir = tempfile::tempdir().unwrap();
    write_take_of(dir.path(), "leaf", "grass", 2, 25, 0.1);
    write_take(dir.path(), "plant", 10, 0.1);
    let listed = frond_console::takes::TakeIndex::new(dir.path().to_path_buf()).list();
    let leaf = &listed["takes"][0];
    assert_eq!(leaf["name"], "leaf", "{listed}");
    assert_eq!(leaf["frames"], 25, "{listed}");
    assert!((leaf["duration_s"].as_f64().unwrap() - 2.4).abs() < 1e-9, "{listed}");
    assert_eq!(listed["takes"][1]["frames"], 10, "{listed}");
}

#[test]
fn a_crafted_token_query_sets_no_cookie_and_splits_nothing() {
    let served = Served::start(&[]);
    let answer =
        served.exchange("GET /?token=x%0d%0aSet-Cookie:%20frond_token=evil%0d%0aX-Evil:%201 HTTP/1.1", b"");
    assert_eq!(status(&answer), 200, "{answer}");
    assert_eq!(header(&answer, "set-cookie"), None, "no token is configured: {answer}");
    assert_eq!(header(&answer, "x-evil"), None, "{answer}");
}

/// Pages that open the pose socket and keep it, read or not, kept every new page out: the
/// 17th was answered 503 for as long as they stayed. Now a new page closes the oldest.
#[test]
fn pages_that_stay_never_keep_a_new_page_out() {
    let c = Served::start(&[]);
    let open = || {
        let mut s = TcpStream::connect(c.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let head = format!(
            "GET /ws HTTP/1.1\r\nHost: {a}\r\nOrigin: http://{a}\r\nUpgrade: websocket\r\n\
             Connection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n",
            a = c.addr
        );
        s.write_all(head.as_bytes()).unwrap();
        let mut got = Vec::new();
        let mut byte = [0u8; 1];
        while !got.ends_with(b"\r\n\r\n") && s.read(&mut byte).unwrap() == 1 {
            got.push(byte[0]);
        }
        (s, String::from_utf8_lossy(&got).into_owned())
    };
    // Never read past their heads.
    let mut pages: Vec<_> = (0..frond_console::server::MAX_SOCKETS)
        .map(|_| {
            let (s, head) = open();
            assert_eq!(status(&head), 101, "{head}");
            s
        })
        .collect();
    let (_newest, head) = open();
    assert_eq!(status(&head), 101, "a new page is served: {head}");
    // The oldest was closed by the server: its reads end (after what was already sent).
    let mut sink = Vec::new();
    let n = pages[0].read_to_end(&mut sink);
    assert!(n.is_ok(), "{n:?}");
    for s in &mut pages[1..] {
        s.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
        let mut buf = [0u8; 65536];
        let still_open = loop {
            match s.read(&mut buf) {
                Ok(0) => break false,
                Ok(_) => {}
                Err(_) => break true,
            }
        };
        assert!(still_open, "only the oldest is closed");
    }
    let a = c.exchange("GET /api/status HTTP/1.1", b"");
    assert!(body(&a).contains("\"sockets_closed\":1"), "{a}");
}

/// A page sends its socket nothing but control frames; tungstenite's default took 64 MiB
/// messages, held while read (1 GiB over the 16 sockets). A message past the limit closes it.
#[test]
fn a_page_that_sends_a_large_message_is_closed() {
    let c = Served::start(&[]);
    let mut s = TcpStream::connect(c.addr).unwrap();
    let head = format!(
        "GET /ws HTTP/1.1\r\nHost: {a}\r\nOrigin: http://{a}\r\nUpgrade: websocket\r\n\
         Connection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n",
        a = c.addr
    );
    s.write_all(head.as_bytes()).unwrap();
    // A masked text frame of 64 KiB (RFC 6455, section 5.2), zero mask: the payload as is.
    let n = 64 * 1024u64;
    let mut frame = vec![0x81, 0x80 | 127];
    frame.extend_from_slice(&n.to_be_bytes());
    frame.extend_from_slice(&[0; 4]);
    frame.resize(frame.len() + n as usize, b'a');
    // The server may close while the frame is still arriving.
    let _ = s.write_all(&frame);
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 65536];
    let closed = loop {
        match s.read(&mut buf) {
            Ok(0) => break true,
            Ok(k) => got.extend_from_slice(&buf[..k]),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => break true,
            Err(_) => break false,
        }
    };
    assert!(got.starts_with(b"HTTP/1.1 101"), "{:?}", String::from_utf8_lossy(&got[..got.len().min(200)]));
    assert!(closed, "the socket stayed open after a 64 KiB message");
}

#[test]
fn a_fields_rig_is_served_by_name_and_only_an_embedded_one_or_the_consoles_own() {
    // A meadow of several rigs: the page asks for each field's rig by the name the daemon
    // publishes. An embedded rig's GLB and node map are served; `--rig`'s under its own name;
    // any other name (a path, a rig a take names) is 404, and the answer does not echo it.
    let files = [("secret.toml", rig_named("secret"))];
    let files: Vec<(&str, &str)> = files.iter().map(|(n, t)| (*n, t.as_str())).collect();
    let c = Served::start_on(&files, &[], Some("{dir}/secret.toml"));
    for name in ["flower", "shrub", "secret"] {
        let a = c.exchange(&format!("GET /api/rigs/{name}.json HTTP/1.1"), b"");
        assert_eq!(status(&a), 200, "{name}: {a}");
        let map: serde_json::Value = serde_json::from_str(body(&a)).unwrap();
        assert_eq!(map["rig"], name, "{map}");
        assert_eq!(map["joints"].as_array().unwrap().len(), 4, "{map}");
        let a = c.exchange(&format!("GET /api/rigs/{name}.glb HTTP/1.1"), b"");
        assert_eq!((status(&a), header(&a, "content-type")), (200, Some("model/gltf-binary")), "{name}");
        assert!(body(&a).starts_with("glTF"), "{name}: a GLB");
    }
    for path in [
        "/api/rigs/%2Fetc%2Fpasswd.glb",
        "/api/rigs/..%2Fsecret.json",
        "/api/rigs/grass",
        "/api/rigs/<b>x</b>.json",
    ] {
        let a = c.exchange(&format!("GET {path} HTTP/1.1"), b"");
        assert_eq!(status(&a), 404, "{path}: {a}");
        assert!(!body(&a).contains("passwd") && !body(&a).contains("<b>"), "{path} echoed: {a}");
        assert!(body(&a).contains("an embedded rig (grass, flower, shrub)"), "{a}");
    }
    let a = c.exchange("POST /api/rigs/grass.glb HTTP/1.1\r\nContent-Length: 0", b"");
    assert_eq!((status(&a), header(&a, "allow")), (405, Some("GET, HEAD")), "{a}");
}
