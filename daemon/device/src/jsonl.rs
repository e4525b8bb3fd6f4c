//! Loading JSONL hand recordings: one `{"t":0.0333,"wrist":[p,y,r],"thumb":[g1,g2,g3]}` per line
//! (seconds, degrees).
//!
//! Lines are parsed by `frond_formats::jsonl::parse_hand_line`; this module adds line numbers,
//! blank-line skipping and, for the virtual glove's schedule, the non-decreasing-time check
//! ([`load_hand_file`]). `--replay` takes the times as they are ([`load_hand_recording`]): a
//! jump, a step back or a repeat is a discontinuity there, as in `frond map`.

use std::path::{Path, PathBuf};

use frond_formats::JsonlError;
use frond_motion::HandSample;

/// Why a hand file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum HandFileError {
    /// The file could not be read.
    #[error("cannot read hand file {path}: {source}")]
    Io {
        /// The hand file.
        path: PathBuf,
        /// The underlying read error.
        source: std::io::Error,
    },
    /// The file is not a regular file, too large, or not text.
    #[error("cannot read hand file {}: {}", .0.path().display(), .0.reason())]
    File(frond_formats::rig_files::FileError),
    /// A line is not a valid hand sample, or its time is earlier than the previous line's.
    #[error("{path}:{line}: {error}")]
    Line {
        /// The hand file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        error: HandLineError,
    },
    /// The file has no samples (empty or only blank lines).
    #[error("{path}: no samples")]
    Empty {
        /// The hand file.
        path: PathBuf,
    },
}

/// Why one line of a hand file is not a sample playback can use.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HandLineError {
    /// The line is not a hand sample (the shared parser's error).
    #[error(transparent)]
    Parse(#[from] JsonlError),
    /// `t` is earlier than the previous line's.
    #[error("t {t} is earlier than the previous line's {previous}")]
    Earlier {
        /// This line's time, seconds.
        t: f64,
        /// The previous line's time, seconds.
        previous: f64,
    },
}

/// Parses one line of the hand format (the shared parser of `frond_motion`, so the device path
/// and `frond map` read files identically).
pub fn parse_hand_line(line: &str) -> Result<HandSample, HandLineError> {
    Ok(frond_formats::jsonl::parse_hand_line(line)?)
}

/// Parses a whole hand file; blank lines are skipped; times must not decrease.
pub fn parse_hand_text(path: &Path, text: &str) -> Result<Vec<HandSample>, HandFileError> {
    parse_lines(path, text, true)
}

/// Parses a whole hand recording; blank lines are skipped; times are kept as they are, in any
/// order (untrusted: the player treats a jump, a step back or a repeat as a discontinuity).
pub fn parse_hand_recording(path: &Path, text: &str) -> Result<Vec<HandSample>, HandFileError> {
    parse_lines(path, text, false)
}

fn parse_lines(path: &Path, text: &str, ordered: bool) -> Result<Vec<HandSample>, HandFileError> {
    let mut out: Vec<HandSample> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let err = |error: HandLineError| HandFileError::Line { path: path.to_owned(), line: i + 1, error };
        let s = parse_hand_line(line).map_err(err)?;
        if ordered
            && let Some(prev) = out.last()
            && s.t < prev.t
        {
            return Err(err(HandLineError::Earlier { t: s.t, previous: prev.t }));
        }
        out.push(s);
    }
    if out.is_empty() {
        return Err(HandFileError::Empty { path: path.to_owned() });
    }
    Ok(out)
}

pub use frond_formats::jsonl::MAX_HAND_FILE_BYTES;

/// Loads a hand file into memory: a regular file of at most [`MAX_HAND_FILE_BYTES`] (a FIFO or
/// a device is refused without blocking); times must not decrease ([`parse_hand_text`]).
pub fn load_hand_file(path: &Path) -> Result<Vec<HandSample>, HandFileError> {
    parse_hand_text(path, &read_hand_text(path)?)
}

/// Loads a hand recording like [`load_hand_file`], its times in any order
/// ([`parse_hand_recording`]).
pub fn load_hand_recording(path: &Path) -> Result<Vec<HandSample>, HandFileError> {
    parse_hand_recording(path, &read_hand_text(path)?)
}

fn read_hand_text(path: &Path) -> Result<String, HandFileError> {
    frond_formats::rig_files::read_small_text(path, MAX_HAND_FILE_BYTES).map_err(|e| match e {
        frond_formats::rig_files::FileError::Read { path, source } => HandFileError::Io { path, source },
        other => HandFileError::File(other),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_line_is_reported_with_its_number() {
        let text = "{\"t\":0,\"wrist\":[1,2,3],\"thumb\":[4,5,6]}\n\n{\"t\":0.1,\"wrist\":[1,2]}\n";
        let e = parse_hand_text(Path::new("x.jsonl"), text).unwrap_err();
        assert!(e.to_string().starts_with("x.jsonl:3: "), "{e}");
        let HandFileError::Line { line: 3, error: HandLineError::Parse(parse), .. } = &e else {
            panic!("{e:?}");
        };
        assert_eq!(e.to_string(), format!("x.jsonl:3: {parse}"), "the parser's own message, unchanged");
    }

    #[test]
    fn decreasing_time_is_an_error() {
        let text =
            "{\"t\":1,\"wrist\":[1,2,3],\"thumb\":[4,5,6]}\n{\"t\":0.5,\"wrist\":[1,2,3],\"thumb\":[4,5,6]}";
        let e = parse_hand_text(Path::new("x"), text).unwrap_err();
        assert!(e.to_string().contains("x:2: t 0.5 is earlier"), "{e}");
        // A recording for `--replay` keeps them (a discontinuity of playback), bad lines still fail.
        let times: Vec<f64> =
            parse_hand_recording(Path::new("x"), text).unwrap().iter().map(|s| s.t).collect();
        assert_eq!(times, [1.0, 0.5]);
        let e = parse_hand_recording(Path::new("x"), "\n{\"t\":1,\"wrist\":[400,0,0],\"thumb\":[0,0,0]}")
            .unwrap_err();
        assert!(e.to_string().starts_with("x:2: `wrist[0]`: 400 degrees"), "{e}");
        assert!(matches!(parse_hand_recording(Path::new("x"), "\n"), Err(HandFileError::Empty { .. })));
    }

    #[test]
    fn parses_values_like_text() {
        let s = parse_hand_line(r#"{"t":0.0333,"wrist":[12.34,-5,0],"thumb":[1,2,3.5]}"#).unwrap();
        assert_eq!(s.t, 0.0333);
        assert_eq!(s.wrist_deg, [12.34, -5.0, 0.0]);
        assert_eq!(s.thumb_deg, [1.0, 2.0, 3.5]);
    }
}
