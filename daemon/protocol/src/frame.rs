//! Length-prefixed, versioned MessagePack framing.
//!
//! ```text
//! +----------------+---------+------------------------+
//! | len: u32 LE    | version | MessagePack body       |
//! | (= 1 + body)   | u8      | (len - 1 bytes)        |
//! +----------------+---------+------------------------+
//! ```
//! Encoding reuses the caller's buffer ([`FrameBuf`]) so that a steady stream allocates nothing
//! once the buffer has grown to the largest message.

use std::io::{self, Read, Write};

use serde::Serialize;
use serde::de::DeserializeOwned;
use thiserror::Error;

/// Version byte written in every frame. Version 2 announces elements
/// ([`crate::ServerMessage::Elements`]) and drives live stages with one family of control
/// requests (`StageStart`, `StageStop`, `StageInput`); version 1 had a request per live mode.
/// Version 3 publishes a field as its definition and frames of its driving stream
/// ([`crate::ServerMessage::Field`], [`crate::field`]) instead of one pose per plant.
pub const PROTOCOL_VERSION: u8 = 3;
/// Bytes before the body: the `u32` length and the version byte.
pub const HEADER_LEN: usize = 5;
/// Largest accepted `len` field. Anything bigger is refused before reading it.
pub const MAX_FRAME_LEN: usize = 1 << 20;
/// Largest control request a daemon accepts, bytes (a rig, a field, a calibration travel in
/// one request, so a client can check its file against this before sending it).
pub const MAX_CONTROL_REQUEST: usize = 256 * 1024;

/// Why a byte string is not a valid frame.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// The length field is zero: a frame needs at least its version byte.
    #[error("frame length is 0; a frame holds at least its version byte")]
    EmptyFrame,
    /// The length field exceeds [`MAX_FRAME_LEN`].
    #[error("frame length {len} exceeds the limit of {max} bytes")]
    TooLarge {
        /// Length announced by the peer.
        len: usize,
        /// The limit.
        max: usize,
    },
    /// The peer speaks a protocol version this build does not know.
    #[error(
        "frond protocol version {got} is not supported (this build speaks version {supported}); {}",
        if got > supported { "upgrade frond on this side" } else { "upgrade the peer (frond, frondd and every exporter must speak the same version)" }
    )]
    UnsupportedVersion {
        /// Version byte found.
        got: u8,
        /// Version this build speaks.
        supported: u8,
    },
    /// The body is not a valid MessagePack encoding of the expected message.
    #[error("malformed message body: {0}")]
    Malformed(String),
    /// Bytes after the message inside the frame.
    #[error("{0} unexpected trailing bytes after the message body")]
    TrailingBytes(usize),
}

/// Error while reading a frame from a stream.
#[derive(Debug, Error)]
pub enum ReadError {
    /// The peer closed the stream cleanly between frames.
    #[error("connection closed")]
    Closed,
    /// The stream ended inside a frame.
    #[error("connection closed in the middle of a frame ({got} of {want} bytes)")]
    Truncated {
        /// Bytes received.
        got: usize,
        /// Bytes expected.
        want: usize,
    },
    /// An I/O error (including read timeouts).
    #[error("i/o error: {0}")]
    Io(#[from] io::Error),
    /// The frame arrived but does not decode.
    #[error(transparent)]
    Decode(#[from] DecodeError),
}

/// A reusable encode buffer.
#[derive(Debug, Default, Clone)]
pub struct FrameBuf {
    bytes: Vec<u8>,
}

impl FrameBuf {
    /// A buffer with room for frames of `capacity` bytes without reallocating.
    pub fn with_capacity(capacity: usize) -> Self {
        FrameBuf { bytes: Vec::with_capacity(capacity) }
    }
    /// Encodes `msg` as one frame, replacing the previous contents, and returns the frame bytes.
    pub fn encode<T: Serialize>(&mut self, msg: &T) -> &[u8] {
        self.bytes.clear();
        encode_frame(msg, &mut self.bytes);
        &self.bytes
    }
    /// The last encoded frame.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }
}

/// Appends one frame holding `msg` to `out`.
///
/// Serialising our own message types into a `Vec` cannot fail; a failure would be a bug in a
/// `Serialize` impl, so it panics with a clear message rather than sending a broken frame.
pub fn encode_frame<T: Serialize>(msg: &T, out: &mut Vec<u8>) {
    encode_frame_as(PROTOCOL_VERSION, msg, out)
}

/// Like [`encode_frame`], with another version byte: for the one message an older peer must
/// still be able to read, the refusal that names both versions (a [`crate::ControlReply::Error`]
/// has the same shape in every version).
pub fn encode_frame_as<T: Serialize>(version: u8, msg: &T, out: &mut Vec<u8>) {
    let start = out.len();
    out.extend_from_slice(&[0, 0, 0, 0, version]);
    let mut ser = rmp_serde::Serializer::new(&mut *out).with_struct_map();
    msg.serialize(&mut ser).expect("frond messages always serialise");
    let len = out.len() - start - 4;
    assert!(len <= MAX_FRAME_LEN, "frame of {len} bytes exceeds MAX_FRAME_LEN");
    out[start..start + 4].copy_from_slice(&(len as u32).to_le_bytes());
}

/// Checks a frame header; returns the total frame length (header included).
fn check_header(header: &[u8; HEADER_LEN]) -> Result<usize, DecodeError> {
    let len = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
    if len == 0 {
        return Err(DecodeError::EmptyFrame);
    }
    if len > MAX_FRAME_LEN {
        return Err(DecodeError::TooLarge { len, max: MAX_FRAME_LEN });
    }
    if header[4] != PROTOCOL_VERSION {
        return Err(DecodeError::UnsupportedVersion { got: header[4], supported: PROTOCOL_VERSION });
    }
    Ok(len + 4)
}

fn decode_body<T: DeserializeOwned>(body: &[u8]) -> Result<T, DecodeError> {
    let mut cursor = body;
    let value = rmp_serde::from_read(&mut cursor).map_err(|e| DecodeError::Malformed(e.to_string()))?;
    if !cursor.is_empty() {
        return Err(DecodeError::TrailingBytes(cursor.len()));
    }
    Ok(value)
}

/// Decodes the first frame in `bytes`.
///
/// Returns `Ok(None)` when `bytes` holds only part of a frame (read more and call again), or the
/// message and the number of bytes it used. Never panics, whatever the input.
pub fn decode_frame<T: DeserializeOwned>(bytes: &[u8]) -> Result<Option<(T, usize)>, DecodeError> {
    let Some(header) = bytes.first_chunk::<HEADER_LEN>() else {
        // A header with a bad length can already be judged from 4 bytes.
        if let Some(len) = bytes.first_chunk::<4>() {
            let len = u32::from_le_bytes(*len) as usize;
            if len == 0 {
                return Err(DecodeError::EmptyFrame);
            }
            if len > MAX_FRAME_LEN {
                return Err(DecodeError::TooLarge { len, max: MAX_FRAME_LEN });
            }
        }
        return Ok(None);
    };
    let total = check_header(header)?;
    if bytes.len() < total {
        return Ok(None);
    }
    let msg = decode_body(&bytes[HEADER_LEN..total])?;
    Ok(Some((msg, total)))
}

/// Reads exactly one frame from `reader`, using `buf` as scratch space.
pub fn read_frame<T: DeserializeOwned, R: Read>(reader: &mut R, buf: &mut Vec<u8>) -> Result<T, ReadError> {
    read_frame_limited(reader, buf, MAX_FRAME_LEN)
}

/// Like [`read_frame`], but refuses frames longer than `max_len` (at most [`MAX_FRAME_LEN`])
/// from their header, before reading or buffering the body.
pub fn read_frame_limited<T: DeserializeOwned, R: Read>(
    reader: &mut R,
    buf: &mut Vec<u8>,
    max_len: usize,
) -> Result<T, ReadError> {
    let mut header = [0u8; HEADER_LEN];
    let got = read_full(reader, &mut header)?;
    if got == 0 {
        return Err(ReadError::Closed);
    }
    if got < HEADER_LEN {
        return Err(ReadError::Truncated { got, want: HEADER_LEN });
    }
    let total = check_header(&header)?;
    let max_len = max_len.min(MAX_FRAME_LEN);
    if total - 4 > max_len {
        return Err(DecodeError::TooLarge { len: total - 4, max: max_len }.into());
    }
    let body_len = total - HEADER_LEN;
    buf.clear();
    buf.resize(body_len, 0);
    let got = read_full(reader, buf)?;
    if got < body_len {
        return Err(ReadError::Truncated { got: HEADER_LEN + got, want: total });
    }
    Ok(decode_body(buf)?)
}

/// Encodes `msg` into `buf` and writes it to `writer` in one `write_all`.
pub fn write_frame<T: Serialize, W: Write>(writer: &mut W, buf: &mut FrameBuf, msg: &T) -> io::Result<()> {
    writer.write_all(buf.encode(msg))
}

/// Reads until `buf` is full or EOF; returns the bytes read.
fn read_full<R: Read>(reader: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}
