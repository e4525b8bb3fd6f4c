//! `frond-relay`: the do-nothing baseline of `frond bench`'s OSC section, built without any of
//! frond's code. It binds a UDP address and a Unix socket, waits for N readers to connect, then
//! forwards every datagram unchanged to each of them as `[u32 little-endian length][bytes]`.
//! What frond's OSC path costs beyond this is what frond adds.
//!
//! Usage: `frond-relay UDP_ADDR SOCKET_PATH READERS` (prints `ready` once the readers are in).

use std::io::Write;
use std::net::UdpSocket;
use std::os::unix::net::UnixListener;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [udp, path, readers] = args.as_slice() else {
        eprintln!("usage: frond-relay UDP_ADDR SOCKET_PATH READERS");
        return ExitCode::from(2);
    };
    let Ok(readers) = readers.parse::<usize>() else {
        eprintln!("frond-relay: READERS must be a number, not {readers:?}");
        return ExitCode::from(2);
    };
    let run = || -> std::io::Result<()> {
        let socket = UdpSocket::bind(udp)?;
        let listener = UnixListener::bind(path)?;
        println!("listening");
        let mut out = Vec::with_capacity(readers);
        while out.len() < readers {
            out.push(listener.accept()?.0);
        }
        println!("ready");
        let mut buf = vec![0u8; 65_536 + 4];
        loop {
            let n = socket.recv(&mut buf[4..])?;
            buf[..4].copy_from_slice(&(n as u32).to_le_bytes());
            out.retain_mut(|s| s.write_all(&buf[..4 + n]).is_ok());
            if out.is_empty() {
                return Ok(());
            }
        }
    };
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("frond-relay: {e}");
            ExitCode::FAILURE
        }
    }
}
