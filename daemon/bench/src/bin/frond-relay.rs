//! `frond-relay`: the do-nothing baseline of `frond bench`'s latency and CPU sections, built
//! without any of frond's code (std and libc only). It opens its input and a Unix socket, waits
//! for N readers to connect, then forwards every datagram or report unchanged to each of them as
//! `[u32 little-endian length][bytes]`. What frond's path costs beyond this is what frond adds.
//!
//! Usage: `frond-relay SOURCE SOCKET_PATH READERS`, where SOURCE is
//! - `udp:ADDR`: a UDP socket bound to ADDR, one datagram per `recv`;
//! - `hidraw:PATH`: a hidraw node (or the virtual glove's FUSE node), opened non-blocking,
//!   `poll(2)`ed for `POLLIN`, one report per `read(2)`, as a hidraw reader does.
//!
//! Prints `listening` once the socket is bound and the input open, `ready` once the readers are in.

use std::fs::File;
use std::io::{Read, Write};
use std::net::UdpSocket;
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::os::unix::net::UnixListener;
use std::process::ExitCode;

/// Where the bytes come from.
enum Input {
    Udp(UdpSocket),
    Hidraw(File),
}

impl Input {
    fn open(source: &str) -> std::io::Result<Input> {
        if let Some(addr) = source.strip_prefix("udp:") {
            Ok(Input::Udp(UdpSocket::bind(addr)?))
        } else if let Some(path) = source.strip_prefix("hidraw:") {
            let file = File::options().read(true).custom_flags(libc::O_NONBLOCK).open(path)?;
            Ok(Input::Hidraw(file))
        } else {
            Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("SOURCE must be udp:ADDR or hidraw:PATH, not {source:?}"),
            ))
        }
    }

    /// The next datagram or report into `buf`; its length.
    fn recv(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let file = match self {
            Input::Udp(socket) => return socket.recv(buf),
            Input::Hidraw(file) => file,
        };
        loop {
            let mut pfd = libc::pollfd { fd: file.as_raw_fd(), events: libc::POLLIN, revents: 0 };
            // SAFETY: `pfd` is one valid, writable pollfd for an open descriptor.
            if unsafe { libc::poll(&mut pfd, 1, -1) } < 0 {
                let e = std::io::Error::last_os_error();
                if e.kind() == std::io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(e);
            }
            if pfd.revents & libc::POLLIN == 0 && pfd.revents & (libc::POLLERR | libc::POLLHUP) != 0 {
                return Err(std::io::Error::other("the hidraw device is gone"));
            }
            match file.read(buf) {
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => continue,
                other => return other,
            }
        }
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [source, path, readers] = args.as_slice() else {
        eprintln!("frond-relay: error: usage: frond-relay udp:ADDR|hidraw:PATH SOCKET_PATH READERS");
        return ExitCode::from(2);
    };
    let Ok(readers) = readers.parse::<usize>() else {
        eprintln!("frond-relay: error: READERS must be a number, not {readers:?}");
        return ExitCode::from(2);
    };
    let run = || -> std::io::Result<()> {
        let mut input = Input::open(source)?;
        let listener = UnixListener::bind(path)?;
        println!("listening");
        let mut out = Vec::with_capacity(readers);
        while out.len() < readers {
            out.push(listener.accept()?.0);
        }
        println!("ready");
        let mut buf = vec![0u8; 65_536 + 4];
        loop {
            let n = input.recv(&mut buf[4..])?;
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
            eprintln!("frond-relay: {source}: {e}");
            ExitCode::FAILURE
        }
    }
}
