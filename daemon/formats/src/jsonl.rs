//! JSON Lines codec for hand samples and poses (one object a line).
//!
//! Hand lines: `{"t":0.0333,"wrist":[pitch,yaw,roll],"thumb":[g1,g2,g3]}` (degrees, seconds).
//! Pose lines: `{"seq":N,"t":..,"joints":[[p,y,r],[p,y,r],[p,y,r],[p,y,r]]}` (`seq` optional).
//!
//! Numbers are parsed as `f64` and then cast to `f32` with `as` (what serde_json does by default
//! for an `f32` field). The parse goes through [`serde_json::Value`], so it stays the same even if
//! another crate in the build enables serde_json's `float_roundtrip` feature. The virtual glove and
//! `frond map` both read hand files through this module, so live and offline mapping see
//! bit-identical inputs.
//!
//! Unknown fields are ignored (forward compatibility); missing, mistyped, wrongly sized and
//! non-finite fields are errors that name the field. Callers add the line number.

use std::io;

use serde::Serialize;
use serde_json::{Map, Value};
use thiserror::Error;

use frond_motion::sample::{HandSample, JOINTS, PoseFrame};

/// Why a line could not be parsed. The `field` strings are paths such as `wrist[1]` or
/// `joints[2][0]`.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum JsonlError {
    /// The line is not valid JSON (serde_json's message, with its column).
    #[error("not JSON: {0}")]
    NotJson(String),
    /// The line is JSON but not an object.
    #[error("expected a JSON object, found {0}")]
    NotObject(&'static str),
    /// A required field is absent.
    #[error("missing field `{0}`")]
    MissingField(&'static str),
    /// A field has the wrong JSON type.
    #[error("field `{field}`: expected {expected}, found {found}")]
    WrongType {
        /// Path of the field.
        field: String,
        /// What was expected.
        expected: &'static str,
        /// The JSON type found.
        found: &'static str,
    },
    /// An array field has the wrong number of elements.
    #[error("field `{field}`: expected {expected} elements, found {found}")]
    WrongLength {
        /// Path of the field.
        field: String,
        /// Required length.
        expected: usize,
        /// Length found.
        found: usize,
    },
    /// A number does not fit the target type (overflows `f32` to infinity, or is negative or
    /// fractional where an unsigned integer is required).
    #[error("field `{field}`: {value} is not {expected}")]
    OutOfRange {
        /// Path of the field.
        field: String,
        /// The number as written in the JSON.
        value: String,
        /// What was expected, e.g. "a finite 32-bit float".
        expected: &'static str,
    },
    /// A hand sample outside the plausibility limits every hand source applies.
    #[error(transparent)]
    Implausible(#[from] frond_motion::plausible::Implausible),
}

fn type_name(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn parse_object(line: &str) -> Result<Map<String, Value>, JsonlError> {
    let v: Value = serde_json::from_str(line).map_err(|e| JsonlError::NotJson(e.to_string()))?;
    match v {
        Value::Object(m) => Ok(m),
        other => Err(JsonlError::NotObject(type_name(&other))),
    }
}

fn field<'a>(obj: &'a Map<String, Value>, name: &'static str) -> Result<&'a Value, JsonlError> {
    obj.get(name).ok_or(JsonlError::MissingField(name))
}

fn number(v: &Value, path: impl FnOnce() -> String) -> Result<f64, JsonlError> {
    match v {
        // serde_json only produces finite f64 values (it rejects overflowing literals).
        Value::Number(n) => n.as_f64().ok_or_else(|| JsonlError::OutOfRange {
            field: path(),
            value: n.to_string(),
            expected: "a 64-bit float",
        }),
        other => Err(JsonlError::WrongType { field: path(), expected: "a number", found: type_name(other) }),
    }
}

fn float32(v: &Value, path: impl Fn() -> String) -> Result<f32, JsonlError> {
    let x = number(v, &path)?;
    // serde_json's default f32 conversion: parse as f64, then `as`.
    let y = x as f32;
    if y.is_finite() {
        Ok(y)
    } else {
        Err(JsonlError::OutOfRange { field: path(), value: x.to_string(), expected: "a finite 32-bit float" })
    }
}

fn array(v: &Value, len: usize, path: impl Fn() -> String) -> Result<&[Value], JsonlError> {
    match v {
        Value::Array(a) if a.len() == len => Ok(a),
        Value::Array(a) => Err(JsonlError::WrongLength { field: path(), expected: len, found: a.len() }),
        other => Err(JsonlError::WrongType { field: path(), expected: "an array", found: type_name(other) }),
    }
}

fn vec3(v: &Value, name: &str) -> Result<[f32; 3], JsonlError> {
    let a = array(v, 3, || name.to_string())?;
    let mut out = [0.0; 3];
    for (k, (o, x)) in out.iter_mut().zip(a).enumerate() {
        *o = float32(x, || format!("{name}[{k}]"))?;
    }
    Ok(out)
}

fn time(obj: &Map<String, Value>) -> Result<f64, JsonlError> {
    number(field(obj, "t")?, || "t".to_string())
}

/// Largest hand file loaded whole (`--replay`, `frond take import`), bytes: about an hour of
/// 1 kHz samples.
pub const MAX_HAND_FILE_BYTES: u64 = 512 << 20;

/// Parses one hand line `{"t":..,"wrist":[pitch,yaw,roll],"thumb":[g1,g2,g3]}`, refusing a
/// sample no live source would accept ([`HandSample::check_plausible`]).
pub fn parse_hand_line(line: &str) -> Result<HandSample, JsonlError> {
    let obj = parse_object(line)?;
    let t = time(&obj)?;
    let wrist_deg = vec3(field(&obj, "wrist")?, "wrist")?;
    let thumb_deg = vec3(field(&obj, "thumb")?, "thumb")?;
    let hand = HandSample { t, wrist_deg, thumb_deg };
    // The limits every live source applies (`frond_motion::plausible`).
    hand.check_plausible()?;
    Ok(hand)
}

/// Parses one pose line `{"seq":N,"t":..,"joints":[[p,y,r],x4]}`, returning the optional `seq`.
pub fn parse_pose_line_with_seq(line: &str) -> Result<(Option<u64>, PoseFrame), JsonlError> {
    let obj = parse_object(line)?;
    let seq = match obj.get("seq") {
        None => None,
        Some(Value::Number(n)) => Some(n.as_u64().ok_or_else(|| JsonlError::OutOfRange {
            field: "seq".to_string(),
            value: n.to_string(),
            expected: "an unsigned 64-bit integer",
        })?),
        Some(other) => {
            return Err(JsonlError::WrongType {
                field: "seq".to_string(),
                expected: "an unsigned integer",
                found: type_name(other),
            });
        }
    };
    let t = time(&obj)?;
    let joints = array(field(&obj, "joints")?, JOINTS, || "joints".to_string())?;
    let mut joints_deg = [[0.0; 3]; JOINTS];
    for (i, (o, j)) in joints_deg.iter_mut().zip(joints).enumerate() {
        *o = vec3(j, &format!("joints[{i}]"))?;
    }
    Ok((seq, PoseFrame { t, joints_deg }))
}

/// Parses one pose line; an optional `"seq"` field is checked and dropped.
pub fn parse_pose_line(line: &str) -> Result<PoseFrame, JsonlError> {
    parse_pose_line_with_seq(line).map(|(_, p)| p)
}

/// `io::Write` into a `String`. serde_json only hands it complete UTF-8 sequences (here ASCII).
struct StringWriter<'a>(&'a mut String);

impl io::Write for StringWriter<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let s = std::str::from_utf8(buf).map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))?;
        self.0.push_str(s);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[derive(Serialize)]
struct PoseLine<'a> {
    #[serde(skip_serializing_if = "Option::is_none")]
    seq: Option<u64>,
    t: f64,
    joints: &'a [[f32; 3]; JOINTS],
}

#[derive(Serialize)]
struct HandLine<'a> {
    t: f64,
    wrist: &'a [f32; 3],
    thumb: &'a [f32; 3],
}

fn write_json<T: Serialize>(v: &T, out: &mut String) {
    // Writing numbers and ASCII keys into a String cannot fail: StringWriter only errors on
    // invalid UTF-8, and serde_json never fails on these plain structs.
    let _ = serde_json::to_writer(StringWriter(out), v);
}

/// Appends `{"seq":N,"t":..,"joints":[[p,y,r],...]}` (no newline; `seq` omitted when `None`).
///
/// Floats use serde_json's shortest round-trip formatting of the `f32`/`f64` values, so
/// [`parse_pose_line`] gives back the identical frame. Non-finite values are written as `null`
/// (serde_json's convention) and are rejected when read back.
pub fn write_pose_line(frame: &PoseFrame, seq: Option<u64>, out: &mut String) {
    write_json(&PoseLine { seq, t: frame.t, joints: &frame.joints_deg }, out);
}

/// Appends `{"t":..,"wrist":[p,y,r],"thumb":[g1,g2,g3]}` (no newline).
pub fn write_hand_line(hand: &HandSample, out: &mut String) {
    write_json(&HandLine { t: hand.t, wrist: &hand.wrist_deg, thumb: &hand.thumb_deg }, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_hand_line() {
        let h = parse_hand_line(r#"{"t":0.0333,"wrist":[10,-20.5,3],"thumb":[1,2,3.25]}"#).unwrap();
        assert_eq!(h.t, 0.0333);
        assert_eq!(h.wrist_deg, [10.0, -20.5, 3.0]);
        assert_eq!(h.thumb_deg, [1.0, 2.0, 3.25]);
    }

    #[test]
    fn numbers_go_through_f64_then_as_f32() {
        // 0.1 as f64 then `as f32` is the nearest f32 to the nearest f64 to 0.1.
        let h = parse_hand_line(r#"{"t":0,"wrist":[0.1,0,0],"thumb":[0,0,0]}"#).unwrap();
        assert_eq!(h.wrist_deg[0], 0.1f64 as f32);
        // A double-rounding case: 1 + 2^-24 + 2^-60 rounds to f64 as 1 + 2^-24 (a tie in f32),
        // which then rounds to even (1.0). Directly to f32 it would round up.
        let h = parse_hand_line(r#"{"t":0,"wrist":[1.00000005960464477539062500087,0,0],"thumb":[0,0,0]}"#)
            .unwrap();
        assert_eq!(h.wrist_deg[0], 1.0);
    }

    #[test]
    fn hand_errors_name_the_field() {
        let cases = [
            ("nope", "not JSON"),
            ("[1,2]", "expected a JSON object, found an array"),
            (r#"{"wrist":[0,0,0],"thumb":[0,0,0]}"#, "missing field `t`"),
            (r#"{"t":0,"thumb":[0,0,0]}"#, "missing field `wrist`"),
            (r#"{"t":0,"wrist":[0,0],"thumb":[0,0,0]}"#, "field `wrist`: expected 3 elements, found 2"),
            (
                r#"{"t":0,"wrist":[0,0,0],"thumb":[0,"x",0]}"#,
                "field `thumb[1]`: expected a number, found a string",
            ),
            (
                r#"{"t":0,"wrist":[0,1e39,0],"thumb":[0,0,0]}"#,
                "field `wrist[1]`: 1000000000000000000000000000000000000000 is not a finite 32-bit float",
            ),
            (r#"{"t":"0","wrist":[0,0,0],"thumb":[0,0,0]}"#, "field `t`: expected a number, found a string"),
            (r#"{"t":0,"wrist":null,"thumb":[0,0,0]}"#, "field `wrist`: expected an array, found null"),
            // The limits every live source applies (issue 14, point 11).
            (
                r#"{"t":0,"wrist":[400,0,0],"thumb":[0,0,0]}"#,
                "`wrist[0]`: 400 degrees is not a hand angle (finite, within ±360)",
            ),
            (
                r#"{"t":0,"wrist":[0,0,0],"thumb":[0,0,-1e30]}"#,
                "`thumb[2]`: -1000000000000000000000000000000 degrees is not a hand angle",
            ),
            (
                r#"{"t":-0.5,"wrist":[0,0,0],"thumb":[0,0,0]}"#,
                "`t`: -0.5 is not a finite time at or after 0 s",
            ),
        ];
        for (line, want) in cases {
            let e = parse_hand_line(line).unwrap_err().to_string();
            assert!(e.starts_with(want), "{line}: got {e:?}, want {want:?}");
        }
    }

    #[test]
    fn pose_line_round_trip_is_exact() {
        let p = PoseFrame {
            t: 1.0 / 30.0,
            joints_deg: [
                [0.1, -2.5, 0.0],
                [1e-7, 123.456, -0.0],
                [f32::MAX, f32::MIN_POSITIVE, 7.0],
                [-1.0 / 3.0, 2.0 / 3.0, 1e30],
            ],
        };
        let mut s = String::new();
        write_pose_line(&p, Some(42), &mut s);
        assert!(s.starts_with(r#"{"seq":42,"t":0.03333333333333333,"joints":[[0.1,-2.5,0.0],"#), "{s}");
        let (seq, q) = parse_pose_line_with_seq(&s).unwrap();
        assert_eq!(seq, Some(42));
        assert_eq!(q, p);
        // Bit-exact, including the sign of zero.
        assert!(q.joints_deg[1][2].is_sign_negative());
    }

    #[test]
    fn pose_line_without_seq() {
        let p = PoseFrame { t: 2.0, joints_deg: [[1.0, 2.0, 3.0]; 4] };
        let mut s = String::new();
        write_pose_line(&p, None, &mut s);
        assert_eq!(s, r#"{"t":2.0,"joints":[[1.0,2.0,3.0],[1.0,2.0,3.0],[1.0,2.0,3.0],[1.0,2.0,3.0]]}"#);
        assert_eq!(parse_pose_line(&s).unwrap(), p);
        assert_eq!(parse_pose_line_with_seq(&s).unwrap().0, None);
    }

    #[test]
    fn pose_errors_name_the_field() {
        let cases = [
            (r#"{"t":0,"joints":[[0,0,0],[0,0,0],[0,0,0]]}"#, "field `joints`: expected 4 elements, found 3"),
            (
                r#"{"t":0,"joints":[[0,0,0],[0,0,0],[0,0],[0,0,0]]}"#,
                "field `joints[2]`: expected 3 elements, found 2",
            ),
            (
                r#"{"t":0,"joints":[[0,0,0],[0,0,0],[0,0,0],[0,0,true]]}"#,
                "field `joints[3][2]`: expected a number, found a boolean",
            ),
            (
                r#"{"t":0,"joints":[[0,0,0],[0,0,0],[0,0,0],[0,0,null]]}"#,
                "field `joints[3][2]`: expected a number, found null",
            ),
            (
                r#"{"seq":-1,"t":0,"joints":[[0,0,0],[0,0,0],[0,0,0],[0,0,0]]}"#,
                "field `seq`: -1 is not an unsigned 64-bit integer",
            ),
            (
                r#"{"seq":"1","t":0,"joints":[[0,0,0],[0,0,0],[0,0,0],[0,0,0]]}"#,
                "field `seq`: expected an unsigned integer, found a string",
            ),
            (r#"{"t":0}"#, "missing field `joints`"),
        ];
        for (line, want) in cases {
            let e = parse_pose_line(line).unwrap_err().to_string();
            assert!(e.starts_with(want), "{line}: got {e:?}, want {want:?}");
        }
    }

    #[test]
    fn hand_line_round_trip() {
        let h = HandSample { t: 0.125, wrist_deg: [0.1, -45.0, 1e-3], thumb_deg: [30.5, 0.0, -1.0] };
        let mut s = String::new();
        write_hand_line(&h, &mut s);
        assert_eq!(s, r#"{"t":0.125,"wrist":[0.1,-45.0,0.001],"thumb":[30.5,0.0,-1.0]}"#);
        assert_eq!(parse_hand_line(&s).unwrap(), h);
    }

    #[test]
    fn unknown_fields_are_ignored() {
        let h = parse_hand_line(r#"{"t":1,"wrist":[0,0,0],"thumb":[0,0,0],"flex":[1,2,3,4]}"#);
        assert!(h.is_ok());
    }
}
