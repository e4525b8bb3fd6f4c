//! Leap Motion / Ultraleap hands as frond hand samples (seed 000, section 5.1: "we are able to
//! track the wrist's motions and the thumb joints' bending angles" with the Leap Motion SDK).
//!
//! Input: the JSON of the tracking service's WebSocket, protocol v6 (LeapJS 0.6-1.1; what
//! Ultraleap's open-source tracking WebSocket server speaks on `ws://HOST:6437/v6.json`): first
//! `{"version": 6}`, then one frame a message, `{"id", "timestamp" (microseconds), "hands": [{"id",
//! "type": "left"|"right", "direction", "palmNormal", ...}], "pointables": [{"handId", "type" (0 =
//! thumb), "bases": 4 bones x 3x3, ...}]}`, millimetres, right-handed, +Y up, +Z towards the user.
//!
//! Wrist angles are the SDK's own (LeapJS `Hand.pitch/yaw/roll`): pitch `atan2(d.y, -d.z)`, yaw
//! `atan2(d.x, -d.z)`, roll `atan2(n.x, -n.y)` of the palm direction `d` and normal `n`. The thumb's
//! three bend angles are the angles between its successive bones (metacarpal-proximal,
//! proximal-intermediate, intermediate-distal), each bone's direction the negated third row of
//! its basis (LeapJS `Bone.direction`). Pure: parsing and math only.

use std::fmt;
use std::marker::PhantomData;

use serde::Deserialize;
use serde::de::{Deserializer, Error as _, IgnoredAny, SeqAccess, Visitor};

use frond_motion::HandSample;
use frond_motion::hand_landmarks::{bend_deg, palm_angles_deg};

/// Largest message accepted, bytes (a one-hand v6 frame of a real controller is about 4.7 KB,
/// two hands about 10 KB; [`MAX_HANDS`] hands fit ten times over). The WebSocket client
/// refuses a longer message from its header, before reading it.
pub const MAX_MESSAGE_BYTES: usize = 512 << 10;
/// Most hands a frame may list.
pub const MAX_HANDS: usize = 8;
/// Most pointables a frame may list (5 per hand).
pub const MAX_POINTABLES: usize = 5 * MAX_HANDS;

/// Which hand drives the plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Chirality {
    /// The left hand.
    Left,
    /// The right hand.
    Right,
}

impl Chirality {
    /// `left` or `right`, as the v6 protocol names hands.
    pub fn as_str(self) -> &'static str {
        match self {
            Chirality::Left => "left",
            Chirality::Right => "right",
        }
    }
}

/// One hand of a frame (the fields frond uses).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct LeapHand {
    /// Tracking id.
    pub id: i64,
    /// `left` or `right`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Unit vector from the palm towards the fingers.
    pub direction: [f64; 3],
    /// Unit vector out of the palm (down when the palm faces down).
    pub palm_normal: [f64; 3],
}

/// One finger of a frame (the fields frond uses).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct LeapPointable {
    /// The hand's tracking id.
    pub hand_id: i64,
    /// 0 thumb, 1 index, 2 middle, 3 ring, 4 pinky.
    #[serde(rename = "type")]
    pub kind: i64,
    /// Bases of the metacarpal, proximal, intermediate and distal bones (rows: x, y, z axes).
    pub bases: [[[f64; 3]; 3]; 4],
}

/// One tracking frame.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct LeapFrame {
    /// Frame id (increases by one per tracking frame).
    pub id: i64,
    /// Device time, microseconds.
    pub timestamp: i64,
    /// The hands seen (at most [`MAX_HANDS`]).
    #[serde(default, deserialize_with = "at_most::<_, _, MAX_HANDS>")]
    pub hands: Vec<LeapHand>,
    /// Their fingers (at most [`MAX_POINTABLES`]).
    #[serde(default, deserialize_with = "at_most::<_, _, MAX_POINTABLES>")]
    pub pointables: Vec<LeapPointable>,
}

/// What a frame lists, by the name of its list (for [`LeapError::TooMany`]).
trait Listed {
    /// The frame's key of the list.
    const LIST: &'static str;
}

impl Listed for LeapHand {
    const LIST: &'static str = "hands";
}

impl Listed for LeapPointable {
    const LIST: &'static str = "pointables";
}

/// The parse error of a list longer than `max`: said the same way by the visitor and
/// recognised by [`parse_message`].
fn too_many_text(list: &str, max: usize) -> String {
    format!("more than {max} {list} in one frame")
}

/// A frame's list read item by item up to `MAX`: one item more ends the parse there, with
/// nothing after it read, so that a frame listing 5,000 hands costs what one of 9 does, not
/// 5,000 hands' worth of parsing and memory.
fn at_most<'de, D, T, const MAX: usize>(d: D) -> Result<Vec<T>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Listed,
{
    struct Items<T, const MAX: usize>(PhantomData<T>);

    impl<'de, T: Deserialize<'de> + Listed, const MAX: usize> Visitor<'de> for Items<T, MAX> {
        type Value = Vec<T>;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "a list of at most {MAX} {}", T::LIST)
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<T>, A::Error> {
            let mut items = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(MAX));
            while items.len() < MAX {
                match seq.next_element()? {
                    Some(item) => items.push(item),
                    None => return Ok(items),
                }
            }
            if seq.next_element::<IgnoredAny>()?.is_some() {
                return Err(A::Error::custom(too_many_text(T::LIST, MAX)));
            }
            Ok(items)
        }
    }

    d.deserialize_seq(Items::<T, MAX>(PhantomData))
}

/// Any message of the stream, read in one pass: the fields that tell a version from a frame
/// from anything else, the lists bounded while they are read, every other field skipped
/// without being kept.
#[derive(Deserialize)]
struct AnyMessage {
    version: Option<i64>,
    id: Option<i64>,
    timestamp: Option<i64>,
    #[serde(default, deserialize_with = "some_at_most::<_, _, MAX_HANDS>")]
    hands: Option<Vec<LeapHand>>,
    #[serde(default, deserialize_with = "some_at_most::<_, _, MAX_POINTABLES>")]
    pointables: Option<Vec<LeapPointable>>,
}

/// [`at_most`] for a list that may be missing.
fn some_at_most<'de, D, T, const MAX: usize>(d: D) -> Result<Option<Vec<T>>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Listed,
{
    at_most::<D, T, MAX>(d).map(Some)
}

/// A message of the v6 stream.
#[derive(Debug, Clone, PartialEq)]
pub enum LeapMessage {
    /// `{"version": N}`, the first message.
    Version(i64),
    /// A tracking frame.
    Frame(LeapFrame),
    /// Anything else the service sends (events, `serviceVersion`, ...): ignored.
    Other,
}

/// Why a message was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LeapError {
    /// Larger than [`MAX_MESSAGE_BYTES`].
    #[error("message of {0} bytes is larger than {MAX_MESSAGE_BYTES}")]
    TooLarge(usize),
    /// Not JSON, or a frame with missing or mistyped fields.
    #[error("not a v6 message: {0}")]
    Json(String),
    /// More hands or pointables than a frame can have (refused at the first one too many,
    /// before the rest of the frame is read).
    #[error("a frame listing more than {max} {list}")]
    TooMany {
        /// The list: `hands` or `pointables`.
        list: &'static str,
        /// Its limit ([`MAX_HANDS`] or [`MAX_POINTABLES`]).
        max: usize,
    },
    /// A non-finite number or a zero vector where a direction belongs.
    #[error("hand {0}: a direction, normal or bone basis is not a finite non-zero vector")]
    BadVector(i64),
}

/// Parses one message, in one pass and bounded while it is read: larger than
/// [`MAX_MESSAGE_BYTES`], or listing more than [`MAX_HANDS`] hands or [`MAX_POINTABLES`]
/// pointables, is refused before the rest is read, and nothing but the frame's own fields is
/// kept.
pub fn parse_message(text: &str) -> Result<LeapMessage, LeapError> {
    if text.len() > MAX_MESSAGE_BYTES {
        return Err(LeapError::TooLarge(text.len()));
    }
    let message: AnyMessage = serde_json::from_str(text).map_err(|e| {
        let said = e.to_string();
        let lists = [(LeapHand::LIST, MAX_HANDS), (LeapPointable::LIST, MAX_POINTABLES)];
        match lists.into_iter().find(|&(list, max)| said.starts_with(&too_many_text(list, max))) {
            Some((list, max)) => LeapError::TooMany { list, max },
            None => LeapError::Json(said),
        }
    })?;
    let AnyMessage { version, id, timestamp, hands, pointables } = message;
    if let (Some(v), None) = (version, &hands) {
        return Ok(LeapMessage::Version(v));
    }
    let (Some(id), Some(timestamp)) = (id, timestamp) else { return Ok(LeapMessage::Other) };
    Ok(LeapMessage::Frame(LeapFrame {
        id,
        timestamp,
        hands: hands.unwrap_or_default(),
        pointables: pointables.unwrap_or_default(),
    }))
}

fn usable(v: &[f64; 3]) -> bool {
    v.iter().all(|c| c.is_finite()) && v.iter().map(|c| c * c).sum::<f64>() > 1e-12
}

/// Wrist `[pitch, yaw, roll]`, degrees, from the palm direction and normal (LeapJS's
/// definitions, shared with the camera source: [`frond_motion::hand_landmarks::palm_angles_deg`]).
pub fn wrist_deg(direction: [f64; 3], palm_normal: [f64; 3]) -> [f32; 3] {
    palm_angles_deg(direction, palm_normal)
}

/// The three bend angles of a finger, degrees: between its successive bones' directions
/// ([`frond_motion::hand_landmarks::bend_deg`]), each the negated third row of its basis.
pub fn bends_deg(bases: &[[[f64; 3]; 3]; 4]) -> [f32; 3] {
    let dir = |b: &[[f64; 3]; 3]| b[2].map(|c| -c);
    std::array::from_fn(|i| bend_deg(dir(&bases[i]), dir(&bases[i + 1])))
}

/// The hand sample of the chosen hand in `frame` (`t` its device time in seconds), or `None`
/// when that hand (or its thumb) is not in the frame.
pub fn hand_sample(frame: &LeapFrame, which: Chirality) -> Result<Option<HandSample>, LeapError> {
    let Some(hand) = frame.hands.iter().find(|h| h.kind == which.as_str()) else { return Ok(None) };
    let Some(thumb) = frame.pointables.iter().find(|p| p.hand_id == hand.id && p.kind == 0) else {
        return Ok(None);
    };
    let bases_ok = thumb.bases.iter().all(|b| b.iter().all(usable));
    if !usable(&hand.direction) || !usable(&hand.palm_normal) || !bases_ok {
        return Err(LeapError::BadVector(hand.id));
    }
    Ok(Some(HandSample {
        t: frame.timestamp as f64 / 1e6,
        wrist_deg: wrist_deg(hand.direction, hand.palm_normal),
        thumb_deg: bends_deg(&thumb.bases),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of the basis of a bone pointing along `dir` (unit), `x` a unit vector across it.
    fn basis(dir: [f64; 3], x: [f64; 3]) -> [[f64; 3]; 3] {
        let z = dir.map(|c| -c);
        let y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]];
        [x, y, z]
    }

    fn frame(direction: [f64; 3], normal: [f64; 3], bends_deg: [f64; 3]) -> String {
        // A thumb pointing forward (-Z), bending about +X by the given angles, bone after bone.
        let mut angle: f64 = 0.0;
        let mut bases = vec![basis([0.0, 0.0, -1.0], [1.0, 0.0, 0.0])];
        for b in bends_deg {
            angle += b.to_radians();
            bases.push(basis([0.0, -angle.sin(), -angle.cos()], [1.0, 0.0, 0.0]));
        }
        serde_json::json!({
            "currentFrameRate": 110.0, "devices": [], "id": 42, "timestamp": 1_500_000,
            "hands": [{"id": 7, "type": "right", "direction": direction, "palmNormal": normal,
                       "confidence": 1.0, "palmPosition": [0.0, 200.0, 0.0]}],
            "pointables": [{"handId": 7, "id": 70, "type": 0, "bases": bases, "extended": true}]
        })
        .to_string()
    }

    #[test]
    fn a_level_hand_is_the_zero_pose_and_angles_are_worked_out_by_hand() {
        // Palm down, fingers away from the user (-Z): pitch, yaw and roll 0.
        let text = frame([0.0, 0.0, -1.0], [0.0, -1.0, 0.0], [10.0, 20.0, 30.0]);
        let LeapMessage::Frame(f) = parse_message(&text).unwrap() else { panic!() };
        let s = hand_sample(&f, Chirality::Right).unwrap().unwrap();
        assert_eq!(s.t, 1.5);
        assert_eq!(s.wrist_deg.map(f32::abs), [0.0, 0.0, 0.0]);
        for (got, want) in s.thumb_deg.iter().zip([10.0, 20.0, 30.0]) {
            assert!((got - want).abs() < 1e-4, "{:?}", s.thumb_deg);
        }
        // Fingers raised 30 degrees: d = (0, sin 30, -cos 30) -> pitch 30.
        let h = 30f64.to_radians();
        assert!((wrist_deg([0.0, h.sin(), -h.cos()], [0.0, -1.0, 0.0])[0] - 30.0).abs() < 1e-4);
        // Turned 45 degrees to the right: d = (sin 45, 0, -cos 45) -> yaw 45.
        let q = 45f64.to_radians();
        assert!((wrist_deg([q.sin(), 0.0, -q.cos()], [0.0, -1.0, 0.0])[1] - 45.0).abs() < 1e-4);
        // Rolled: the normal tips to +X by 20 degrees: n = (sin 20, -cos 20, 0) -> roll 20.
        let r = 20f64.to_radians();
        assert!((wrist_deg([0.0, 0.0, -1.0], [r.sin(), -r.cos(), 0.0])[2] - 20.0).abs() < 1e-4);
        // The other hand is not there.
        assert_eq!(hand_sample(&f, Chirality::Left).unwrap(), None);
    }

    proptest::proptest! {
        #[test]
        fn any_text_or_damaged_frame_is_an_answer_never_a_panic(
            junk in ".{0,200}",
            cut in 0usize..2000,
            byte in 0usize..2000,
            with in proptest::prelude::any::<u8>(),
        ) {
            let _ = parse_message(&junk);
            let good = frame([0.1, 0.2, -1.0], [0.0, -1.0, 0.1], [5.0, 6.0, 7.0]);
            let mut bytes = good.into_bytes();
            let at = byte % bytes.len();
            bytes[at] = with;
            bytes.truncate(cut.max(1).min(bytes.len()));
            if let Ok(text) = std::str::from_utf8(&bytes)
                && let Ok(LeapMessage::Frame(f)) = parse_message(text)
                && let Ok(Some(s)) = hand_sample(&f, Chirality::Right)
            {
                proptest::prop_assert!(s.wrist_deg.iter().chain(&s.thumb_deg).all(|a| a.is_finite()));
            }
        }
    }

    #[test]
    fn bad_messages_are_refused_by_name() {
        assert_eq!(parse_message(r#"{"version": 6}"#).unwrap(), LeapMessage::Version(6));
        assert_eq!(parse_message(r#"{"event": {"type": "deviceConnect"}}"#).unwrap(), LeapMessage::Other);
        assert!(matches!(parse_message("not json"), Err(LeapError::Json(_))));
        assert!(matches!(parse_message(&" ".repeat(MAX_MESSAGE_BYTES + 1)), Err(LeapError::TooLarge(_))));
        let bad = frame([0.0, 0.0, -1.0], [0.0, -1.0, 0.0], [1.0, 1.0, 1.0])
            .replace("\"timestamp\":1500000", "\"timestamp\":\"x\"");
        assert!(matches!(parse_message(&bad), Err(LeapError::Json(_))), "{bad}");
        let zero = frame([0.0, 0.0, 0.0], [0.0, -1.0, 0.0], [1.0, 1.0, 1.0]);
        let LeapMessage::Frame(f) = parse_message(&zero).unwrap() else { panic!() };
        assert_eq!(hand_sample(&f, Chirality::Right), Err(LeapError::BadVector(7)));
        let hands: Vec<_> = (0..9).map(|i| serde_json::json!({"id": i, "type": "left", "direction": [0,0,-1], "palmNormal": [0,-1,0]})).collect();
        let many = serde_json::json!({"id": 1, "timestamp": 0, "hands": hands}).to_string();
        assert_eq!(parse_message(&many), Err(LeapError::TooMany { list: "hands", max: MAX_HANDS }));
        let fingers: Vec<_> = (0..=MAX_POINTABLES)
            .map(|i| serde_json::json!({"handId": 1, "type": i % 5, "bases": [[[1,0,0],[0,1,0],[0,0,1]], [[1,0,0],[0,1,0],[0,0,1]], [[1,0,0],[0,1,0],[0,0,1]], [[1,0,0],[0,1,0],[0,0,1]]]}))
            .collect();
        let many = serde_json::json!({"id": 1, "timestamp": 0, "pointables": fingers}).to_string();
        assert_eq!(parse_message(&many), Err(LeapError::TooMany { list: "pointables", max: MAX_POINTABLES }));
        // At the limit, the frame is read.
        let hands: Vec<_> = (0..MAX_HANDS).map(|i| serde_json::json!({"id": i, "type": "left", "direction": [0,0,-1], "palmNormal": [0,-1,0]})).collect();
        let eight = serde_json::json!({"id": 1, "timestamp": 0, "hands": hands}).to_string();
        assert!(matches!(parse_message(&eight), Ok(LeapMessage::Frame(f)) if f.hands.len() == MAX_HANDS));
    }

    /// Issue 42: a frame listing 5,000 hands is refused at the ninth, before the other 4,991
    /// (and anything after them) are read: the hand after the ninth is not even valid JSON, so
    /// a parser that read them all would call the frame malformed, not too many.
    #[test]
    fn a_frame_of_thousands_of_hands_is_refused_at_the_first_one_too_many() {
        let hand = r#"{"id":1,"type":"left","direction":[0,0,-1],"palmNormal":[0,-1,0]}"#;
        let mut text = String::from(r#"{"id":1,"timestamp":0,"hands":["#);
        for i in 0..5000 {
            if i > 0 {
                text.push(',');
            }
            // The tenth hand on is garbage: never looked at.
            text.push_str(if i < MAX_HANDS + 1 { hand } else { "@" });
        }
        text.push_str("]}");
        assert!(text.len() < MAX_MESSAGE_BYTES);
        assert_eq!(parse_message(&text), Err(LeapError::TooMany { list: "hands", max: MAX_HANDS }));
        // The same frame of well-formed hands is refused the same way.
        let whole = format!(r#"{{"id":1,"timestamp":0,"hands":[{}]}}"#, vec![hand; 5000].join(","));
        assert_eq!(parse_message(&whole), Err(LeapError::TooMany { list: "hands", max: MAX_HANDS }));
    }

    /// Messages that are not frames are told apart as before the bounded reader.
    #[test]
    fn versions_frames_and_other_messages_are_told_apart() {
        let v = r#"{"serviceVersion": "5.17.1", "version": 6}"#;
        assert_eq!(parse_message(v).unwrap(), LeapMessage::Version(6));
        assert_eq!(parse_message(r#"{"id": 3}"#).unwrap(), LeapMessage::Other);
        let f =
            parse_message(r#"{"id": 3, "timestamp": 9, "devices": [{"x": [1, 2, {"y": null}]}]}"#).unwrap();
        assert_eq!(
            f,
            LeapMessage::Frame(LeapFrame { id: 3, timestamp: 9, hands: vec![], pointables: vec![] })
        );
        assert!(matches!(parse_message(r#"{"version": "six"}"#), Err(LeapError::Json(_))));
        assert!(matches!(parse_message("[1, 2]"), Err(LeapError::Json(_))));
    }
}
