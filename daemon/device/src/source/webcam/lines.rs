//! The landmark helper's lines (`frond-hands`, protocol 1), parsed with bounds, and a frame's
//! chosen hand as a hand sample. Pure: text in, values out.
//!
//! One JSON object a line: first `{"v":1,"hello":"frond-hands","model":...}`, then per frame
//! `{"v":1,"seq":N,"t_us":T,"model_us":M,"w":W,"h":H,"hands":[{"side":"left"|"right","score":S,
//! "world":[63 numbers],"image":[63 numbers]}]}`, or `{"v":1,"error":"..."}` before it exits.
//! The helper is frond's own, but what it prints is still checked as if anyone wrote it: a line
//! longer than [`MAX_LINE_BYTES`] is refused before it is parsed, at most [`MAX_HANDS`] hands,
//! exactly 63 finite numbers a landmark set, sizes and times in range.

use serde::Deserialize;

use frond_motion::HandSample;
use frond_motion::hand_landmarks::{HandPoints, Handedness, LANDMARKS, LandmarkError, hand_sample};

/// Longest line taken (two hands of 126 numbers each fit about four times over).
pub const MAX_LINE_BYTES: usize = 16 << 10;
/// Most hands a frame may list.
pub const MAX_HANDS: usize = 4;
/// The protocol version this reader speaks.
pub const PROTOCOL: u32 = 1;
/// Longest text of a hello or error line kept.
const MAX_TEXT: usize = 200;

/// One hand of a frame.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct HandLine {
    /// `left` or `right` (the user's hand, in the selfie view).
    pub side: String,
    /// The model's confidence in the handedness, 0 to 1.
    pub score: f64,
    /// World landmarks, metres: 21 x (x, y, z).
    pub world: Vec<f64>,
    /// Image landmarks, normalised: 21 x (x, y, z).
    pub image: Vec<f64>,
}

/// One frame's landmarks.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct FrameLine {
    /// Frame number from the helper's start.
    pub seq: u64,
    /// Capture time, CLOCK_MONOTONIC microseconds (untrusted: the reader checks it).
    pub t_us: u64,
    /// The model's time on the frame, microseconds.
    pub model_us: u64,
    /// Frame width, pixels.
    pub w: u32,
    /// Frame height, pixels.
    pub h: u32,
    /// The hands found (at most [`MAX_HANDS`]).
    pub hands: Vec<HandLine>,
}

/// A line of the helper.
#[derive(Debug, Clone, PartialEq)]
pub enum HelperLine {
    /// The first line: the model it runs.
    Hello {
        /// The model's name and version.
        model: String,
    },
    /// A frame's landmarks.
    Frame(FrameLine),
    /// The helper's last word before it exits.
    Error(String),
}

/// Why a line was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LineError {
    /// Longer than [`MAX_LINE_BYTES`].
    #[error("line of {0} bytes is longer than {MAX_LINE_BYTES}")]
    TooLong(usize),
    /// Not JSON, or a line of no known shape.
    #[error("not a frond-hands line: {0}")]
    Json(String),
    /// Another protocol version.
    #[error("protocol version {0}, expected {PROTOCOL}")]
    Version(u64),
    /// More hands than a frame may list.
    #[error("a frame listing more than {MAX_HANDS} hands")]
    TooMany,
    /// A value out of its range (a landmark list not 63 numbers, a size or score out of range).
    #[error("{0}")]
    OutOfRange(&'static str),
}

#[derive(Deserialize)]
struct AnyLine {
    v: u64,
    hello: Option<String>,
    model: Option<String>,
    error: Option<String>,
    #[serde(flatten)]
    frame: Option<FrameLine>,
}

fn cut(text: &str) -> String {
    text.chars().take(MAX_TEXT).collect()
}

/// Parses one line (without its newline), bounded: too long is refused before it is read.
pub fn parse_line(text: &str) -> Result<HelperLine, LineError> {
    if text.len() > MAX_LINE_BYTES {
        return Err(LineError::TooLong(text.len()));
    }
    let line: AnyLine = serde_json::from_str(text).map_err(|e| LineError::Json(cut(&e.to_string())))?;
    if line.v != u64::from(PROTOCOL) {
        return Err(LineError::Version(line.v));
    }
    if let Some(error) = line.error {
        return Ok(HelperLine::Error(cut(&error)));
    }
    if line.hello.is_some() {
        return Ok(HelperLine::Hello { model: cut(line.model.as_deref().unwrap_or("unknown")) });
    }
    let frame = line.frame.ok_or_else(|| LineError::Json("neither a frame, a hello nor an error".into()))?;
    if frame.hands.len() > MAX_HANDS {
        return Err(LineError::TooMany);
    }
    if !(1..=16384).contains(&frame.w) || !(1..=16384).contains(&frame.h) {
        return Err(LineError::OutOfRange("frame size out of range"));
    }
    for hand in &frame.hands {
        if hand.world.len() != 3 * LANDMARKS || hand.image.len() != 3 * LANDMARKS {
            return Err(LineError::OutOfRange("a hand's landmarks are not 21 x 3 numbers"));
        }
        if !(0.0..=1.0).contains(&hand.score) {
            return Err(LineError::OutOfRange("a hand's score is not 0 to 1"));
        }
        if hand.side != "left" && hand.side != "right" {
            return Err(LineError::OutOfRange("a hand's side is not left or right"));
        }
    }
    Ok(HelperLine::Frame(frame))
}

/// The landmarks of `list` (63 numbers) as 21 points.
fn points(list: &[f64]) -> [[f64; 3]; LANDMARKS] {
    std::array::from_fn(|i| [list[3 * i], list[3 * i + 1], list[3 * i + 2]])
}

/// The chosen hand of `frame` as a hand sample at `t_s` seconds: the most confident hand of
/// that side, from its world landmarks. `None` when that hand is not in the frame; an error
/// when its landmarks make no hand.
pub fn frame_sample(
    frame: &FrameLine,
    which: Handedness,
    t_s: f64,
) -> Option<Result<HandSample, LandmarkError>> {
    let side = match which {
        Handedness::Left => "left",
        Handedness::Right => "right",
    };
    let hand = frame.hands.iter().filter(|h| h.side == side).max_by(|a, b| a.score.total_cmp(&b.score))?;
    Some(HandPoints::world(&points(&hand.world)).and_then(|p| hand_sample(&p, which, t_s)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numbers(n: usize, v: f64) -> String {
        vec![v.to_string(); n].join(",")
    }

    #[test]
    fn hello_error_and_frames_are_told_apart_and_bounded() {
        let hello = r#"{"v":1,"hello":"frond-hands","model":"mediapipe 0.10.21 hands","complexity":1}"#;
        assert_eq!(parse_line(hello), Ok(HelperLine::Hello { model: "mediapipe 0.10.21 hands".into() }));
        assert_eq!(parse_line(r#"{"v":1,"error":"no camera"}"#), Ok(HelperLine::Error("no camera".into())));
        let empty = r#"{"v":1,"seq":3,"t_us":5,"model_us":7,"w":640,"h":480,"hands":[]}"#;
        let Ok(HelperLine::Frame(f)) = parse_line(empty) else { panic!() };
        assert_eq!((f.seq, f.t_us, f.model_us, f.hands.len()), (3, 5, 7, 0));
        assert_eq!(frame_sample(&f, Handedness::Right, 0.0), None);
        let hand = |side: &str, n: usize| {
            format!(
                r#"{{"side":"{side}","score":0.9,"world":[{}],"image":[{}]}}"#,
                numbers(n, 0.1),
                numbers(63, 0.5)
            )
        };
        let frame = |hands: Vec<String>| {
            format!(
                r#"{{"v":1,"seq":1,"t_us":1,"model_us":1,"w":640,"h":480,"hands":[{}]}}"#,
                hands.join(",")
            )
        };
        assert!(matches!(parse_line(&frame(vec![hand("left", 63)])), Ok(HelperLine::Frame(_))));
        assert!(matches!(parse_line(&frame(vec![hand("left", 62)])), Err(LineError::OutOfRange(_))));
        assert!(matches!(parse_line(&frame(vec![hand("up", 63)])), Err(LineError::OutOfRange(_))));
        assert_eq!(parse_line(&frame(vec![hand("left", 63); 5])), Err(LineError::TooMany));
        assert!(matches!(parse_line(&" ".repeat(MAX_LINE_BYTES + 1)), Err(LineError::TooLong(_))));
        assert_eq!(parse_line(r#"{"v":2,"hello":"x"}"#), Err(LineError::Version(2)));
        assert!(matches!(parse_line("not json"), Err(LineError::Json(_))));
        assert!(matches!(parse_line(r#"{"v":1}"#), Err(LineError::Json(_))));
        // Every landmark on one point: a hand of no shape is an error, not an angle.
        let Ok(HelperLine::Frame(f)) = parse_line(&frame(vec![hand("left", 63)])) else { panic!() };
        assert!(matches!(frame_sample(&f, Handedness::Left, 0.0), Some(Err(_))));
        assert_eq!(frame_sample(&f, Handedness::Right, 0.0), None);
    }

    proptest::proptest! {
        #[test]
        fn any_line_is_an_answer_never_a_panic(junk in ".{0,300}", cut in 0usize..400, byte in 0usize..400, with in proptest::prelude::any::<u8>()) {
            let _ = parse_line(&junk);
            let good = format!(
                r#"{{"v":1,"seq":1,"t_us":1,"model_us":1,"w":640,"h":480,"hands":[{{"side":"right","score":0.5,"world":[{}],"image":[{}]}}]}}"#,
                numbers(63, 0.01), numbers(63, 0.5)
            );
            let mut bytes = good.into_bytes();
            let at = byte % bytes.len();
            bytes[at] = with;
            bytes.truncate(cut.max(1).min(bytes.len()));
            if let Ok(text) = std::str::from_utf8(&bytes)
                && let Ok(HelperLine::Frame(f)) = parse_line(text)
                && let Some(Ok(s)) = frame_sample(&f, Handedness::Right, 0.0)
            {
                proptest::prop_assert!(s.wrist_deg.iter().chain(&s.thumb_deg).all(|a| a.is_finite()));
            }
        }
    }
}
