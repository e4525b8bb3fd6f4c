//! One connection to `poses.sock`: an incremental frame reader that survives read timeouts
//! (a partial frame stays buffered) and never trusts the peer's bytes.

use std::io::{self, Read};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::time::Duration;

use frond_protocol::{Hello, ServerMessage, decode_frame};

use crate::error::{ProtocolError, SdkError};
use crate::{SubscriberOptions, check_hello};

/// Bytes read per `read` call.
const READ_CHUNK: usize = 16 * 1024;

pub(crate) struct Conn {
    stream: UnixStream,
    buf: Vec<u8>,
    /// Read scratch space.
    chunk: Box<[u8; READ_CHUNK]>,
    /// Start of unconsumed bytes in `buf`.
    start: usize,
    timeout: Option<Duration>,
}

// A message is as large as a field frame (protocol 3); one outcome lives at a time, on the stack.
#[allow(clippy::large_enum_variant)]
pub(crate) enum ReadOutcome {
    Message(ServerMessage),
    /// Clean close, or the peer vanished mid-frame.
    Closed,
    Err(SdkError),
}

impl Conn {
    /// Connects and reads the hello, waiting at most the options' hello timeout.
    pub(crate) fn open(path: &Path, opts: &SubscriberOptions) -> Result<(Conn, Hello), SdkError> {
        let stream = UnixStream::connect(path)
            .map_err(|source| SdkError::NotRunning { path: path.to_owned(), source })?;
        let mut conn = Conn {
            stream,
            buf: Vec::with_capacity(READ_CHUNK),
            chunk: Box::new([0; READ_CHUNK]),
            start: 0,
            timeout: None,
        };
        let hello = match conn.read_message(path, Some(opts.hello_timeout)) {
            ReadOutcome::Message(ServerMessage::Hello(hello)) => hello,
            ReadOutcome::Message(ServerMessage::Refused(reason)) => {
                return Err(SdkError::Refused { path: path.to_owned(), reason });
            }
            ReadOutcome::Message(
                ServerMessage::Pose(_) | ServerMessage::Elements(_) | ServerMessage::Field(_),
            ) => {
                return Err(SdkError::Protocol {
                    path: path.to_owned(),
                    error: ProtocolError::ExpectedHello,
                });
            }
            ReadOutcome::Closed => {
                return Err(SdkError::Io {
                    path: path.to_owned(),
                    source: io::Error::new(io::ErrorKind::UnexpectedEof, "closed before sending a hello"),
                });
            }
            ReadOutcome::Err(e) => return Err(e),
        };
        check_hello(&hello).map_err(|error| SdkError::Protocol { path: path.to_owned(), error })?;
        Ok((conn, hello))
    }

    fn set_timeout(&mut self, timeout: Option<Duration>) -> io::Result<()> {
        if self.timeout != timeout {
            self.stream.set_read_timeout(timeout)?;
            self.timeout = timeout;
        }
        Ok(())
    }

    /// Reads one message, or reports why not.
    pub(crate) fn read_message(&mut self, path: &Path, timeout: Option<Duration>) -> ReadOutcome {
        if let Err(source) = self.set_timeout(timeout) {
            return ReadOutcome::Err(SdkError::Io { path: path.to_owned(), source });
        }
        loop {
            match decode_frame::<ServerMessage>(&self.buf[self.start..]) {
                Ok(Some((msg, used))) => {
                    self.start += used;
                    if self.start == self.buf.len() {
                        self.buf.clear();
                        self.start = 0;
                    }
                    return ReadOutcome::Message(msg);
                }
                Ok(None) => {}
                Err(e) => {
                    return ReadOutcome::Err(SdkError::Protocol { path: path.to_owned(), error: e.into() });
                }
            }
            if self.start > 0 {
                self.buf.drain(..self.start);
                self.start = 0;
            }
            match self.stream.read(&mut self.chunk[..]) {
                Ok(n @ 1..) => self.buf.extend_from_slice(&self.chunk[..n]),
                Ok(0) => {
                    if !self.buf.is_empty() {
                        tracing::warn!(
                            path = %path.display(),
                            bytes = self.buf.len(),
                            "connection closed in the middle of a frame"
                        );
                    }
                    return ReadOutcome::Closed;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                    return ReadOutcome::Err(SdkError::Timeout {
                        path: path.to_owned(),
                        timeout: timeout.unwrap_or_default(),
                    });
                }
                Err(e) if is_disconnect(&e) => return ReadOutcome::Closed,
                Err(source) => return ReadOutcome::Err(SdkError::Io { path: path.to_owned(), source }),
            }
        }
    }
}

fn is_disconnect(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionReset | io::ErrorKind::ConnectionAborted | io::ErrorKind::BrokenPipe
    )
}
