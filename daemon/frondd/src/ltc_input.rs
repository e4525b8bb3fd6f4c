//! Where the `frond-ltc` thread reads the stage's LTC audio from (issue 46): a regular file or a
//! FIFO of raw mono signed 16-bit little-endian samples, or a WAV file (RIFF, PCM, 16-bit,
//! mono), whose header is read here with every length bounded by the file's.
//!
//! A FIFO is opened non-blocking (opening never waits for a writer, so the daemon starts and
//! stops whether or not the capture runs) and reopened when its writer goes away, so a
//! restarted `arecord` is read again. A regular file is a recording played as the stage's
//! clock: the thread paces its reads in real time. An ALSA capture device (`alsa:DEVICE`) is
//! read by `ltc_alsa`; [`LtcSource`] says which.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::os::fd::AsFd;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::time::Duration;

use frond_ltc::{MAX_SAMPLE_RATE_HZ, MIN_SAMPLE_RATE_HZ};

/// Most bytes of WAV chunks read before the `data` chunk (a header is a few dozen).
const MAX_WAV_HEADER_BYTES: u64 = 64 * 1024;

/// Where the configuration says LTC comes from (`ltc.input`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LtcSource {
    /// A file or FIFO of raw s16le mono samples, or a WAV file.
    Path(PathBuf),
    /// An ALSA capture device (`alsa:DEVICE`).
    Alsa(String),
}

impl LtcSource {
    /// Reads `ltc.input`: `alsa:DEVICE` names an ALSA capture device (a file whose name starts
    /// so is given as `./alsa:...`), anything else a path.
    pub fn parse(text: &str) -> Result<LtcSource, String> {
        if text.trim().is_empty() {
            return Err("must name a file, a FIFO or alsa:DEVICE".into());
        }
        match text.strip_prefix("alsa:") {
            Some(device) => {
                crate::ltc_alsa::check_device_name(device).map_err(|e| e.to_string())?;
                Ok(LtcSource::Alsa(device.to_string()))
            }
            None => Ok(LtcSource::Path(PathBuf::from(text))),
        }
    }
}

impl std::fmt::Display for LtcSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LtcSource::Path(path) => write!(f, "{}", path.display()),
            LtcSource::Alsa(device) => write!(f, "alsa:{device}"),
        }
    }
}

/// Why an LTC input was refused.
#[derive(Debug, thiserror::Error)]
pub enum LtcInputError {
    /// The path could not be opened or read.
    #[error("ltc input {}: {source}", path.display())]
    Io {
        /// The input.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Not a file, a FIFO, or a WAV file frond reads.
    #[error("ltc input {}: {why}", path.display())]
    Format {
        /// The input.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    /// An ALSA capture device could not be opened as asked.
    #[error("ltc input: {0}")]
    Alsa(#[from] crate::ltc_alsa::AlsaError),
}

/// What kind of input it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// A file of raw samples or a WAV file: read paced in real time, "ended" at its end.
    File,
    /// A FIFO (a capture streaming into it): read as it comes, reopened when its writer leaves.
    Fifo,
}

/// What a read gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Read16 {
    /// This many samples were put at the start of the buffer.
    Samples(usize),
    /// Nothing yet (a FIFO with no data, or no writer).
    Nothing,
    /// A file's end.
    End,
}

/// An open LTC input.
#[derive(Debug)]
pub struct LtcInput {
    path: PathBuf,
    kind: InputKind,
    file: File,
    /// The sample rate: the WAV header's, or the configured one.
    sample_rate_hz: u32,
    /// Bytes of sample data left in a file (a WAV's `data` chunk may end before the file).
    remaining: Option<u64>,
    /// A byte of a sample split between two reads.
    odd: Option<u8>,
    bytes: Vec<u8>,
}

impl LtcInput {
    /// Opens `path`, at `sample_rate_hz` unless it is a WAV file (whose header says its rate).
    pub fn open(path: &Path, sample_rate_hz: u32) -> Result<LtcInput, LtcInputError> {
        let io = |source| LtcInputError::Io { path: path.to_path_buf(), source };
        let format = |why: String| LtcInputError::Format { path: path.to_path_buf(), why };
        let meta = std::fs::metadata(path).map_err(io)?;
        let kind = if meta.file_type().is_fifo() {
            InputKind::Fifo
        } else if meta.is_file() {
            InputKind::File
        } else {
            return Err(format(
                "is neither a file nor a FIFO (give a file or FIFO of raw s16le mono samples, or a WAV file)"
                    .into(),
            ));
        };
        let file = open_file(path, kind).map_err(io)?;
        let mut input = LtcInput {
            path: path.to_path_buf(),
            kind,
            file,
            sample_rate_hz,
            remaining: None,
            odd: None,
            bytes: Vec::new(),
        };
        if kind == InputKind::File {
            input.read_header(meta.len()).map_err(|e| match e {
                HeaderError::Io(source) => io(source),
                HeaderError::Format(why) => format(why),
            })?;
        }
        Ok(input)
    }

    /// A WAV file's header (the file then reads from its `data` chunk), or a raw file's checks.
    fn read_header(&mut self, len: u64) -> Result<(), HeaderError> {
        let mut head = [0u8; 12];
        let got = read_up_to(&mut self.file, &mut head)?;
        let is_riff = got >= 4 && &head[..4] == b"RIFF";
        let named_wav = self.path.extension().is_some_and(|e| e.eq_ignore_ascii_case("wav"));
        if !is_riff {
            if named_wav {
                return Err(HeaderError::Format("is not a WAV file (it does not start with RIFF)".into()));
            }
            if len % 2 == 1 {
                return Err(HeaderError::Format(format!(
                    "is {len} bytes, an odd number: not raw 16-bit samples (s16le mono) or a WAV file"
                )));
            }
            self.file.seek(SeekFrom::Start(0))?;
            return Ok(());
        }
        if got < 12 || &head[8..12] != b"WAVE" {
            return Err(HeaderError::Format("is a RIFF file but not WAVE audio".into()));
        }
        let wav = parse_wav_chunks(&mut self.file, len)?;
        if !(MIN_SAMPLE_RATE_HZ..=MAX_SAMPLE_RATE_HZ).contains(&wav.sample_rate_hz) {
            return Err(HeaderError::Format(format!(
                "is a WAV file at {} Hz; LTC is read at {MIN_SAMPLE_RATE_HZ} to {MAX_SAMPLE_RATE_HZ} Hz",
                wav.sample_rate_hz
            )));
        }
        self.sample_rate_hz = wav.sample_rate_hz;
        self.remaining = Some(wav.data_len);
        Ok(())
    }

    /// The input's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether it is a file or a FIFO.
    pub fn kind(&self) -> InputKind {
        self.kind
    }

    /// Its sample rate, Hz.
    pub fn sample_rate_hz(&self) -> u32 {
        self.sample_rate_hz
    }

    /// Waits at most `timeout` for a FIFO to have data (or lose its writer); a file is always
    /// ready.
    pub fn wait(&self, timeout: Duration) {
        if self.kind == InputKind::Fifo {
            crate::clock::wait_readable(self.file.as_fd(), timeout);
        }
    }

    /// Samples waiting in a FIFO after what was read (0 for a file, or when unknown): the last
    /// sample read played that long before now.
    pub fn queued_samples(&self) -> u64 {
        if self.kind != InputKind::Fifo {
            return 0;
        }
        use std::os::fd::AsRawFd;
        let mut bytes: libc::c_int = 0;
        // SAFETY: FIONREAD writes one c_int through the valid pointer given; the descriptor is
        // open for the duration of the call.
        let rc =
            unsafe { libc::ioctl(self.file.as_raw_fd(), libc::FIONREAD, &mut bytes as *mut libc::c_int) };
        if rc != 0 {
            return 0;
        }
        (u64::try_from(bytes).unwrap_or(0) + u64::from(self.odd.is_some())) / 2
    }

    /// Reads at most `out.len()` samples into `out`. A FIFO whose writer left is reopened
    /// (reported as [`Read16::Nothing`]).
    pub fn read(&mut self, out: &mut [i16]) -> std::io::Result<Read16> {
        let mut want = out.len() * 2 - usize::from(self.odd.is_some());
        if let Some(left) = self.remaining {
            want = want.min(usize::try_from(left).unwrap_or(usize::MAX));
            if want == 0 {
                return Ok(Read16::End);
            }
        }
        self.bytes.resize(want, 0);
        let got = match self.file.read(&mut self.bytes) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return Ok(Read16::Nothing),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => return Ok(Read16::Nothing),
            Err(e) => return Err(e),
        };
        if got == 0 && want > 0 {
            return match self.kind {
                InputKind::File => Ok(Read16::End),
                InputKind::Fifo => {
                    // No writer (yet, or any more): reopen, so a poll waits for the next one.
                    self.file = open_file(&self.path, InputKind::Fifo)?;
                    self.odd = None;
                    Ok(Read16::Nothing)
                }
            };
        }
        if let Some(left) = self.remaining.as_mut() {
            *left -= got as u64;
        }
        let mut n = 0;
        let mut bytes = self.bytes[..got].iter().copied();
        if let Some(lo) = self.odd.take() {
            match bytes.next() {
                Some(hi) => {
                    out[0] = i16::from_le_bytes([lo, hi]);
                    n = 1;
                }
                None => self.odd = Some(lo),
            }
        }
        loop {
            match (bytes.next(), bytes.next()) {
                (Some(lo), Some(hi)) => {
                    out[n] = i16::from_le_bytes([lo, hi]);
                    n += 1;
                }
                (Some(lo), None) => {
                    self.odd = Some(lo);
                    break;
                }
                _ => break,
            }
        }
        Ok(if n == 0 { Read16::Nothing } else { Read16::Samples(n) })
    }
}

/// Opens `path` for reading: a FIFO non-blocking (opening never waits for a writer).
fn open_file(path: &Path, kind: InputKind) -> std::io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    if kind == InputKind::Fifo {
        options.custom_flags(libc::O_NONBLOCK);
    }
    options.open(path)
}

/// Why a WAV header was refused.
#[derive(Debug)]
enum HeaderError {
    Io(std::io::Error),
    Format(String),
}

impl From<std::io::Error> for HeaderError {
    fn from(e: std::io::Error) -> Self {
        HeaderError::Io(e)
    }
}

/// What a WAV header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct WavFormat {
    sample_rate_hz: u32,
    /// Bytes of samples (the `data` chunk, cut to the file).
    data_len: u64,
}

/// Reads into `buf` until it is full or the reader ends; how many bytes were read.
fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Reads the chunks after `RIFF....WAVE` up to the `data` chunk (leaving the reader at its
/// first sample), checking `fmt ` says PCM, one channel, 16 bits. `len` is the file's length:
/// no chunk is believed past it, and at most [`MAX_WAV_HEADER_BYTES`] are read before `data`.
fn parse_wav_chunks(r: &mut (impl Read + Seek), len: u64) -> Result<WavFormat, HeaderError> {
    let bad = |why: &str| HeaderError::Format(format!("is not a WAV file frond reads: {why}"));
    let mut at = 12u64;
    let mut rate = None;
    loop {
        let mut head = [0u8; 8];
        if read_up_to(r, &mut head)? < 8 {
            return Err(bad("no data chunk"));
        }
        at += 8;
        let size = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
        match &head[..4] {
            b"fmt " => {
                if !(16..=40).contains(&size) {
                    return Err(bad(&format!("a fmt chunk of {size} bytes")));
                }
                let mut fmt = [0u8; 40];
                let got = read_up_to(r, &mut fmt[..size as usize])?;
                if got < size as usize {
                    return Err(bad("the fmt chunk is cut short"));
                }
                let u16_at = |i: usize| u16::from_le_bytes([fmt[i], fmt[i + 1]]);
                let (format, channels, bits) = (u16_at(0), u16_at(2), u16_at(14));
                if format != 1 {
                    return Err(bad(&format!("format {format}, not PCM (1)")));
                }
                if channels != 1 || bits != 16 {
                    return Err(bad(&format!(
                        "{channels} channel(s) of {bits} bits; LTC is read from mono 16-bit PCM"
                    )));
                }
                rate = Some(u32::from_le_bytes([fmt[4], fmt[5], fmt[6], fmt[7]]));
                if size % 2 == 1 {
                    r.seek(SeekFrom::Current(1))?;
                }
            }
            b"data" => {
                let Some(sample_rate_hz) = rate else { return Err(bad("the data chunk comes before fmt")) };
                return Ok(WavFormat { sample_rate_hz, data_len: size.min(len.saturating_sub(at)) });
            }
            _ => {
                // Any other chunk (LIST, fact, ...) is skipped, padded to an even length.
                let skip = size + size % 2;
                if at + skip > MAX_WAV_HEADER_BYTES.min(len) {
                    return Err(bad("chunks before the data run past the file or 64 KiB"));
                }
                r.seek(SeekFrom::Current(skip as i64))?;
            }
        }
        at += size + size % 2;
        if at > MAX_WAV_HEADER_BYTES.min(len) {
            return Err(bad("no data chunk in the first 64 KiB"));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A WAV header written from the RIFF layout by hand: `fmt ` (16 bytes) then `data`.
    fn wav(format: u16, channels: u16, rate: u32, bits: u16, samples: &[i16]) -> Vec<u8> {
        let data: Vec<u8> = samples.iter().flat_map(|s| s.to_le_bytes()).collect();
        let mut out = Vec::new();
        out.extend_from_slice(b"RIFF");
        out.extend_from_slice(&(36 + data.len() as u32).to_le_bytes());
        out.extend_from_slice(b"WAVEfmt ");
        out.extend_from_slice(&16u32.to_le_bytes());
        out.extend_from_slice(&format.to_le_bytes());
        out.extend_from_slice(&channels.to_le_bytes());
        out.extend_from_slice(&rate.to_le_bytes());
        out.extend_from_slice(&(rate * u32::from(channels) * u32::from(bits / 8)).to_le_bytes());
        out.extend_from_slice(&(channels * bits / 8).to_le_bytes());
        out.extend_from_slice(&bits.to_le_bytes());
        out.extend_from_slice(b"data");
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(&data);
        out
    }

    fn read_all(input: &mut LtcInput) -> Vec<i16> {
        let mut out = Vec::new();
        let mut buf = [0i16; 3];
        loop {
            match input.read(&mut buf).unwrap() {
                Read16::Samples(n) => out.extend_from_slice(&buf[..n]),
                Read16::Nothing => {}
                Read16::End => return out,
            }
        }
    }

    #[test]
    fn wav_and_raw_files_read_their_samples_and_bad_ones_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let samples = [1i16, -2, 300, -32768, 32767, 5, 6];
        let path = dir.path().join("ltc.wav");
        std::fs::write(&path, wav(1, 1, 44_100, 16, &samples)).unwrap();
        let mut input = LtcInput::open(&path, 48_000).unwrap();
        assert_eq!((input.kind(), input.sample_rate_hz()), (InputKind::File, 44_100));
        assert_eq!(read_all(&mut input), samples);
        let raw = dir.path().join("ltc.raw");
        std::fs::write(&raw, samples.iter().flat_map(|s| s.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
        let mut input = LtcInput::open(&raw, 48_000).unwrap();
        assert_eq!(input.sample_rate_hz(), 48_000);
        assert_eq!(read_all(&mut input), samples);
        let refused = |name: &str, bytes: &[u8]| {
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).unwrap();
            LtcInput::open(&p, 48_000).unwrap_err().to_string()
        };
        let e = refused("stereo.wav", &wav(1, 2, 48_000, 16, &samples));
        assert!(e.ends_with("stereo.wav: is not a WAV file frond reads: 2 channel(s) of 16 bits; LTC is read from mono 16-bit PCM"), "{e}");
        let e = refused("float.wav", &wav(3, 1, 48_000, 32, &samples));
        assert!(e.contains("format 3, not PCM (1)"), "{e}");
        let e = refused("slow.wav", &wav(1, 1, 4_000, 16, &samples));
        assert!(e.contains("at 4000 Hz; LTC is read at 8000 to 192000 Hz"), "{e}");
        let e = refused("notes.wav", b"hello, this is text\n");
        assert!(e.contains("notes.wav: is not a WAV file (it does not start with RIFF)"), "{e}");
        let e = refused("odd.raw", b"abc");
        assert!(e.contains("an odd number"), "{e}");
        let mut cut = wav(1, 1, 48_000, 16, &samples);
        cut.truncate(30);
        assert!(refused("cut.wav", &cut).contains("is not a WAV file frond reads"));
        let e = LtcInput::open(dir.path(), 48_000).unwrap_err().to_string();
        assert!(e.contains("is neither a file nor a FIFO"), "{e}");
        let e = LtcInput::open(&dir.path().join("absent"), 48_000).unwrap_err().to_string();
        assert!(e.contains("absent: No such file"), "{e}");
    }
}
