//! `frond-relay` forwards every datagram or report unchanged to each of its readers, framed as
//! `[u32 little-endian length][bytes]`, and says `listening` and `ready` when it is.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::UdpSocket;
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::Duration;

struct Relay {
    child: Child,
    out: BufReader<ChildStdout>,
}

impl Drop for Relay {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn relay(source: &str, socket: &Path, readers: usize) -> Relay {
    let mut child = Command::new(env!("CARGO_BIN_EXE_frond-relay"))
        .arg(source)
        .arg(socket)
        .arg(readers.to_string())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let out = BufReader::new(child.stdout.take().unwrap());
    Relay { child, out }
}

fn line(r: &mut Relay) -> String {
    let mut l = String::new();
    r.out.read_line(&mut l).unwrap();
    l.trim().to_string()
}

/// Connects `n` readers once the relay listens, and waits until it says it is ready.
fn readers(r: &mut Relay, socket: &Path, n: usize) -> Vec<UnixStream> {
    assert_eq!(line(r), "listening");
    let streams: Vec<UnixStream> = (0..n)
        .map(|_| {
            let s = UnixStream::connect(socket).unwrap();
            s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            s
        })
        .collect();
    assert_eq!(line(r), "ready");
    streams
}

fn read_message(s: &mut UnixStream) -> Vec<u8> {
    let mut len = [0u8; 4];
    s.read_exact(&mut len).unwrap();
    let mut msg = vec![0u8; u32::from_le_bytes(len) as usize];
    s.read_exact(&mut msg).unwrap();
    msg
}

#[test]
fn udp_datagrams_reach_every_reader_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let socket = dir.path().join("relay.sock");
    let port = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let mut r = relay(&format!("udp:127.0.0.1:{port}"), &socket, 3);
    let mut streams = readers(&mut r, &socket, 3);
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    let datagrams: [&[u8]; 3] = [b"/frond/hand\0", &[0u8; 1], &[7u8; 1500]];
    for d in datagrams {
        sender.send_to(d, ("127.0.0.1", port)).unwrap();
        for s in &mut streams {
            assert_eq!(read_message(s), d);
        }
    }
}

#[test]
fn hidraw_reports_reach_every_reader_unchanged() {
    // A FIFO stands for the node: it polls readable when a report is written and reads one
    // report at a time when each is read before the next is written, as a hidraw node does.
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("hidraw-fifo");
    let c = std::ffi::CString::new(node.to_str().unwrap()).unwrap();
    // SAFETY: `c` is a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let socket = dir.path().join("relay.sock");
    let mut r = relay(&format!("hidraw:{}", node.display()), &socket, 2);
    let mut streams = readers(&mut r, &socket, 2);
    let mut device = std::fs::OpenOptions::new().write(true).open(&node).unwrap();
    for k in 0..5u8 {
        let report: Vec<u8> = (0..64).map(|i| i ^ k).collect();
        device.write_all(&report).unwrap();
        for s in &mut streams {
            assert_eq!(read_message(s), report, "report {k}");
        }
    }
}

#[test]
fn a_bad_source_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_frond-relay"))
        .args(["tcp:1.2.3.4:5"])
        .arg(dir.path().join("s"))
        .arg("1")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("tcp:1.2.3.4:5") && err.contains("udp:ADDR or hidraw:PATH"), "{err}");
}
