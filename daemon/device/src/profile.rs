//! Device profiles: TOML files in `rig-files/devices/` that describe where a hand device's values
//! live in its HID input report, so one parser ([`crate::report::ReportParser`]) serves any glove.
//!
//! ```toml
//! name = "frond reference glove"
//! vendor_id = 0x1209          # vendor_id + product_id, or path, or both (path wins when opening)
//! product_id = 0xF0D1
//! # path = "/dev/hidraw3"
//! report_id = 1               # omit for devices without numbered reports
//! report_len = 64             # bytes, report id included
//! sequence = { offset = 1, type = "u32le" }              # optional
//! device_time = { offset = 5, type = "u32le", unit = "us" }  # optional; unit us or ms
//! checksum = { kind = "sum8", offset = 63 }              # optional
//! status = { offset = 29 }                               # optional u8, bit 0 = tracking ok
//!
//! [[channel]]
//! name = "wrist_pitch"        # wrist_pitch..wrist_roll, thumb_g1..thumb_g3, flex_index..flex_little
//! offset = 9
//! type = "i16le"              # u8 i8 u16le i16le u32le i32le f32le
//! scale = 0.01                # value = raw * scale, in `unit`
//! unit = "deg"                # deg or rad
//! min = -180.0                # physical range in `unit`; reports outside it are rejected
//! max = 180.0
//! ```
//!
//! All six wrist and thumb channels are required; flex channels are optional. Parsing reports every
//! problem with its path (`channel[3].offset: 70 is past report_len 64`) and never panics.

use std::fmt;
use std::path::{Path, PathBuf};

/// A value type inside a report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldType {
    /// `u8`: unsigned byte.
    U8,
    /// `i8`: signed byte.
    I8,
    /// `u16le`: unsigned 16-bit, little-endian.
    U16Le,
    /// `i16le`: signed 16-bit, little-endian.
    I16Le,
    /// `u32le`: unsigned 32-bit, little-endian.
    U32Le,
    /// `i32le`: signed 32-bit, little-endian.
    I32Le,
    /// `f32le`: IEEE 754 single-precision float, little-endian.
    F32Le,
}

impl FieldType {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "u8" => Self::U8,
            "i8" => Self::I8,
            "u16le" => Self::U16Le,
            "i16le" => Self::I16Le,
            "u32le" => Self::U32Le,
            "i32le" => Self::I32Le,
            "f32le" => Self::F32Le,
            _ => return None,
        })
    }

    /// Size in bytes.
    pub const fn size(self) -> usize {
        match self {
            Self::U8 | Self::I8 => 1,
            Self::U16Le | Self::I16Le => 2,
            Self::U32Le | Self::I32Le | Self::F32Le => 4,
        }
    }

    /// Whether this is an unsigned integer (usable for counters).
    pub const fn is_unsigned_int(self) -> bool {
        matches!(self, Self::U8 | Self::U16Le | Self::U32Le)
    }

    /// Width in bits of an unsigned counter of this type.
    pub const fn bits(self) -> u32 {
        (self.size() * 8) as u32
    }

    /// Reads the value at `offset` as `f64`. The caller guarantees `offset + size <= bytes.len()`.
    #[inline]
    pub(crate) fn read_f64(self, bytes: &[u8], offset: usize) -> f64 {
        let b = |i: usize| bytes[offset + i];
        match self {
            Self::U8 => f64::from(b(0)),
            Self::I8 => f64::from(b(0) as i8),
            Self::U16Le => f64::from(u16::from_le_bytes([b(0), b(1)])),
            Self::I16Le => f64::from(i16::from_le_bytes([b(0), b(1)])),
            Self::U32Le => f64::from(u32::from_le_bytes([b(0), b(1), b(2), b(3)])),
            Self::I32Le => f64::from(i32::from_le_bytes([b(0), b(1), b(2), b(3)])),
            Self::F32Le => f64::from(f32::from_le_bytes([b(0), b(1), b(2), b(3)])),
        }
    }

    /// Reads an unsigned counter at `offset`. Only meaningful for unsigned types.
    #[inline]
    pub(crate) fn read_u32(self, bytes: &[u8], offset: usize) -> u32 {
        let b = |i: usize| bytes[offset + i];
        match self {
            Self::U8 | Self::I8 => u32::from(b(0)),
            Self::U16Le | Self::I16Le => u32::from(u16::from_le_bytes([b(0), b(1)])),
            Self::U32Le | Self::I32Le | Self::F32Le => u32::from_le_bytes([b(0), b(1), b(2), b(3)]),
        }
    }
}

/// The channels a hand device can report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ChannelId {
    /// `wrist_pitch`: wrist pitch angle (required).
    WristPitch,
    /// `wrist_yaw`: wrist yaw angle (required).
    WristYaw,
    /// `wrist_roll`: wrist roll angle (required).
    WristRoll,
    /// `thumb_g1`: bend of the thumb joint nearest the palm (required).
    ThumbG1,
    /// `thumb_g2`: bend of the middle thumb joint (required).
    ThumbG2,
    /// `thumb_g3`: bend of the outermost thumb joint (required).
    ThumbG3,
    /// `flex_index`: index finger flex (optional).
    FlexIndex,
    /// `flex_middle`: middle finger flex (optional).
    FlexMiddle,
    /// `flex_ring`: ring finger flex (optional).
    FlexRing,
    /// `flex_little`: little finger flex (optional).
    FlexLittle,
}

impl ChannelId {
    /// All channels, in slot order (the first six are required).
    pub const ALL: [ChannelId; 10] = [
        Self::WristPitch,
        Self::WristYaw,
        Self::WristRoll,
        Self::ThumbG1,
        Self::ThumbG2,
        Self::ThumbG3,
        Self::FlexIndex,
        Self::FlexMiddle,
        Self::FlexRing,
        Self::FlexLittle,
    ];

    /// The name used in profiles.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::WristPitch => "wrist_pitch",
            Self::WristYaw => "wrist_yaw",
            Self::WristRoll => "wrist_roll",
            Self::ThumbG1 => "thumb_g1",
            Self::ThumbG2 => "thumb_g2",
            Self::ThumbG3 => "thumb_g3",
            Self::FlexIndex => "flex_index",
            Self::FlexMiddle => "flex_middle",
            Self::FlexRing => "flex_ring",
            Self::FlexLittle => "flex_little",
        }
    }

    /// Slot index 0..10 (wrist 0..3, thumb 3..6, flex 6..10).
    pub const fn slot(self) -> usize {
        self as usize
    }

    fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.as_str() == s)
    }

    /// Whether every profile must define this channel.
    pub const fn required(self) -> bool {
        self.is_hand_angle()
    }

    /// True for the wrist and thumb angles (the first six), which the hand plausibility limits
    /// of `frond_motion::plausible` bound; the flex channels are not hand angles.
    pub const fn is_hand_angle(self) -> bool {
        self.slot() < 6
    }
}

impl fmt::Display for ChannelId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Angle unit of a channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AngleUnit {
    /// `deg`: degrees, used as is.
    Deg,
    /// `rad`: radians, converted to degrees by the parser.
    Rad,
}

/// Unit of a device time field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeUnit {
    /// `us`: the counter ticks in microseconds.
    Us,
    /// `ms`: the counter ticks in milliseconds (scaled to microseconds by the parser).
    Ms,
}

/// A counter field (sequence or device time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CounterField {
    /// Byte offset of the counter in the report (report id byte included).
    pub offset: usize,
    /// Unsigned integer type of the counter; its width sets where the counter wraps.
    pub ty: FieldType,
}

/// The device time field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TimeField {
    /// Byte offset of the time counter in the report (report id byte included).
    pub offset: usize,
    /// Unsigned integer type of the counter; its width sets where the time wraps.
    pub ty: FieldType,
    /// Tick unit of the counter.
    pub unit: TimeUnit,
}

/// Checksum kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChecksumKind {
    /// The 8-bit wrapping sum of all `report_len` bytes is zero.
    Sum8,
}

/// Checksum description.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Checksum {
    /// How the checksum is computed and checked.
    pub kind: ChecksumKind,
    /// Where the checksum byte sits (documentation and overlap checks; the sum covers all bytes).
    pub offset: usize,
}

/// One channel of the report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Channel {
    /// Which hand value this channel carries.
    pub id: ChannelId,
    /// Byte offset of the raw value in the report (report id byte included).
    pub offset: usize,
    /// Type of the raw value.
    pub ty: FieldType,
    /// Physical value = raw * scale (computed as raw / (1 / scale) in `f64`, see `divisor`).
    pub scale: f64,
    /// `1.0 / scale`, precomputed: dividing by 100 rather than multiplying by 0.01 makes
    /// centidegrees land on the same `f32` as parsing the decimal text.
    pub divisor: f64,
    /// Angle unit of the scaled value (the parser outputs degrees).
    pub unit: AngleUnit,
    /// Lower end of the physical range in `unit`; smaller values reject the report.
    pub min: f64,
    /// Upper end of the physical range in `unit`; larger values reject the report.
    pub max: f64,
}

/// A validated device profile.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceProfile {
    /// Human-readable device name.
    pub name: String,
    /// USB/HID vendor id to enumerate by (set together with `product_id`).
    pub vendor_id: Option<u16>,
    /// USB/HID product id to enumerate by (set together with `vendor_id`).
    pub product_id: Option<u16>,
    /// hidraw node to open directly; wins over vendor/product id when set.
    pub path: Option<PathBuf>,
    /// First byte of every report when the device uses numbered reports.
    pub report_id: Option<u8>,
    /// Report length in bytes, report id included.
    pub report_len: usize,
    /// Report sequence counter, used to count lost reports; `None`: a local counter is used.
    pub sequence: Option<CounterField>,
    /// Device clock; `None`: host monotonic time is used instead.
    pub device_time: Option<TimeField>,
    /// Report checksum; `None`: reports are not checked.
    pub checksum: Option<Checksum>,
    /// Byte offset of the `u8` status byte (bit 0 = tracking ok); `None`: always tracking.
    pub status_offset: Option<usize>,
    /// The channels, in profile order; every required channel is present.
    pub channels: Vec<Channel>,
}

/// One problem found in a profile.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProfileProblem {
    /// Where: `channel[3].offset`, `vendor_id`, ...
    pub path: String,
    /// What is wrong with the value at `path`.
    pub message: String,
}

impl fmt::Display for ProfileProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.message)
    }
}

/// Largest device profile read, bytes.
pub const MAX_PROFILE_FILE_BYTES: u64 = 1 << 20;
/// Longest device name, bytes. The name is shown in `frond status` and the log, so it is also
/// printable (no control characters): a line break in it would draw a line of its own.
pub const MAX_DEVICE_NAME_BYTES: usize = 128;

/// Why a profile could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The profile file could not be read.
    #[error("cannot read device profile {path}: {source}")]
    Io {
        /// The profile file.
        path: PathBuf,
        /// The underlying read error.
        source: std::io::Error,
    },
    /// The file is not a regular file, too large, or not text.
    #[error("cannot read device profile {}: {}", .0.path().display(), .0.reason())]
    File(frond_formats::rig_files::FileError),
    /// The text is not TOML; carries the TOML parser's message.
    #[error("device profile is not valid TOML: {0}")]
    Syntax(String),
    /// The TOML is well-formed but fails validation; carries every problem found.
    #[error("invalid device profile ({} problem(s)):\n  {}", .0.len(), join_problems(.0))]
    Invalid(Vec<ProfileProblem>),
}

fn join_problems(p: &[ProfileProblem]) -> String {
    p.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n  ")
}

/// The reference glove profile shipped in `rig-files/devices/frond-glove.toml`.
pub const FROND_GLOVE_TOML: &str = include_str!("../../../rig-files/devices/frond-glove.toml");

impl DeviceProfile {
    /// Parses and validates a profile from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Self, ProfileError> {
        let table: toml::Table = toml::from_str(text).map_err(|e| ProfileError::Syntax(e.to_string()))?;
        Checker::default().profile(&table)
    }

    /// Loads a profile file (a regular file of at most [`MAX_PROFILE_FILE_BYTES`]).
    pub fn load(path: &Path) -> Result<Self, ProfileError> {
        let text =
            frond_formats::rig_files::read_small_text(path, MAX_PROFILE_FILE_BYTES).map_err(|e| match e {
                frond_formats::rig_files::FileError::Read { path, source } => {
                    ProfileError::Io { path, source }
                }
                other => ProfileError::File(other),
            })?;
        Self::from_toml_str(&text)
    }

    /// The reference glove profile (embedded copy of `frond-glove.toml`).
    pub fn frond_glove() -> Self {
        Self::from_toml_str(FROND_GLOVE_TOML).unwrap_or_else(|e| {
            // The embedded file is checked by a unit test; this cannot happen in a release.
            unreachable!("embedded frond-glove.toml is invalid: {e}")
        })
    }

    /// Channel for `id`, if the profile defines it.
    pub fn channel(&self, id: ChannelId) -> Option<&Channel> {
        self.channels.iter().find(|c| c.id == id)
    }
}

#[derive(Default)]
struct Checker {
    problems: Vec<ProfileProblem>,
}

/// The keys a `[[channel]]` table may have.
pub const CHANNEL_KEYS: &[&str] = &["name", "offset", "type", "scale", "unit", "min", "max"];

/// The keys a profile's top-level table may have (anything else is reported as unknown).
pub const PROFILE_KEYS: &[&str] = &[
    "name",
    "vendor_id",
    "product_id",
    "path",
    "report_id",
    "report_len",
    "sequence",
    "device_time",
    "checksum",
    "status",
    "channel",
];

impl Checker {
    fn err(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.problems.push(ProfileProblem { path: path.into(), message: message.into() });
    }

    fn unknown_keys(&mut self, t: &toml::Table, prefix: &str, known: &[&str]) {
        for k in t.keys() {
            if !known.contains(&k.as_str()) {
                self.err(format!("{prefix}{k}"), "unknown key");
            }
        }
    }

    fn int(&mut self, t: &toml::Table, key: &str, path: &str, min: i64, max: i64) -> Option<i64> {
        match t.get(key)? {
            toml::Value::Integer(v) if (min..=max).contains(v) => Some(*v),
            toml::Value::Integer(v) => {
                self.err(path, format!("{v} is out of range {min}..={max}"));
                None
            }
            other => {
                self.err(path, format!("expected an integer, got {}", other.type_str()));
                None
            }
        }
    }

    fn float(&mut self, t: &toml::Table, key: &str, path: &str) -> Option<f64> {
        let v = match t.get(key)? {
            toml::Value::Float(v) => *v,
            toml::Value::Integer(v) => *v as f64,
            other => {
                self.err(path, format!("expected a number, got {}", other.type_str()));
                return None;
            }
        };
        if !v.is_finite() {
            self.err(path, "must be a finite number");
            return None;
        }
        Some(v)
    }

    fn string<'a>(&mut self, t: &'a toml::Table, key: &str, path: &str) -> Option<&'a str> {
        match t.get(key)? {
            toml::Value::String(s) => Some(s),
            other => {
                self.err(path, format!("expected a string, got {}", other.type_str()));
                None
            }
        }
    }

    fn table<'a>(&mut self, t: &'a toml::Table, key: &str) -> Option<&'a toml::Table> {
        match t.get(key)? {
            toml::Value::Table(s) => Some(s),
            other => {
                self.err(key, format!("expected a table, got {}", other.type_str()));
                None
            }
        }
    }

    fn field_type(&mut self, t: &toml::Table, path: &str) -> Option<FieldType> {
        let s = self.string(t, "type", path)?;
        let ty = FieldType::parse(s);
        if ty.is_none() {
            self.err(
                path,
                format!("unknown type {s:?} (expected u8, i8, u16le, i16le, u32le, i32le or f32le)"),
            );
        }
        ty
    }

    /// Checks `offset + size <= report_len`; `len` is `None` when report_len itself is invalid.
    fn fits(&mut self, path: &str, offset: usize, size: usize, len: Option<usize>, has_id: bool) {
        if let Some(len) = len {
            if offset >= len {
                self.err(path, format!("{offset} is past report_len {len}"));
            } else if offset + size > len {
                self.err(path, format!("a {size}-byte field at {offset} runs past report_len {len}"));
            }
        }
        if has_id && offset == 0 {
            self.err(path, "0 overlaps the report id byte");
        }
    }

    fn required<T>(&mut self, v: Option<T>, t: &toml::Table, key: &str, path: &str) -> Option<T> {
        if v.is_none() && !t.contains_key(key) {
            self.err(path, "missing");
        }
        v
    }

    fn counter(
        &mut self,
        t: &toml::Table,
        name: &str,
        len: Option<usize>,
        has_id: bool,
        extra: &[&str],
    ) -> Option<(usize, FieldType)> {
        let p = |k: &str| format!("{name}.{k}");
        let mut known = vec!["offset", "type"];
        known.extend_from_slice(extra);
        self.unknown_keys(t, &format!("{name}."), &known);
        let offset = self.int(t, "offset", &p("offset"), 0, 4095);
        let offset = self.required(offset, t, "offset", &p("offset"));
        let ty = self.field_type(t, &p("type"));
        let ty = self.required(ty, t, "type", &p("type"));
        if let Some(ty) = ty
            && !ty.is_unsigned_int()
        {
            self.err(p("type"), "must be an unsigned integer type (u8, u16le, u32le)");
        }
        let (offset, ty) = (offset? as usize, ty?);
        self.fits(&p("offset"), offset, ty.size(), len, has_id);
        Some((offset, ty))
    }

    fn profile(mut self, t: &toml::Table) -> Result<DeviceProfile, ProfileError> {
        self.unknown_keys(t, "", PROFILE_KEYS);
        let name = self.string(t, "name", "name").map(str::to_owned);
        let name = self.required(name, t, "name", "name");
        if let Some(n) = &name {
            if n.trim().is_empty() {
                self.err("name", "must not be empty");
            } else if n.len() > MAX_DEVICE_NAME_BYTES {
                self.err("name", format!("is {} bytes; the limit is {MAX_DEVICE_NAME_BYTES}", n.len()));
            } else if let Some(c) = n.chars().find(|c| c.is_control()) {
                self.err("name", format!("contains the control character {c:?}; a name must be printable"));
            }
        }
        let vendor_id = self.int(t, "vendor_id", "vendor_id", 0, 0xFFFF).map(|v| v as u16);
        let product_id = self.int(t, "product_id", "product_id", 0, 0xFFFF).map(|v| v as u16);
        let path = self.string(t, "path", "path").map(PathBuf::from);
        match (t.contains_key("vendor_id"), t.contains_key("product_id")) {
            (true, false) => self.err("product_id", "missing (vendor_id is set)"),
            (false, true) => self.err("vendor_id", "missing (product_id is set)"),
            (false, false) if !t.contains_key("path") => {
                self.err("vendor_id", "missing: give vendor_id and product_id, or path")
            }
            _ => {}
        }
        let report_id = self.int(t, "report_id", "report_id", 0, 255).map(|v| v as u8);
        let has_id = report_id.is_some();
        let report_len = self.int(t, "report_len", "report_len", 1, 4096);
        let report_len = self.required(report_len, t, "report_len", "report_len").map(|v| v as usize);
        if has_id && report_len == Some(1) {
            self.err("report_len", "1 leaves no room after the report id");
        }

        let sequence = match self.table(t, "sequence") {
            Some(s) => self
                .counter(s, "sequence", report_len, has_id, &[])
                .map(|(offset, ty)| CounterField { offset, ty }),
            None => None,
        };
        let device_time = match self.table(t, "device_time") {
            Some(s) => {
                let c = self.counter(s, "device_time", report_len, has_id, &["unit"]);
                let unit = match self.string(s, "unit", "device_time.unit") {
                    Some("us") => Some(TimeUnit::Us),
                    Some("ms") => Some(TimeUnit::Ms),
                    Some(other) => {
                        self.err("device_time.unit", format!("unknown unit {other:?} (expected us or ms)"));
                        None
                    }
                    None => None,
                };
                let unit = self.required(unit, s, "unit", "device_time.unit");
                match (c, unit) {
                    (Some((offset, ty)), Some(unit)) => Some(TimeField { offset, ty, unit }),
                    _ => None,
                }
            }
            None => None,
        };
        let checksum = match self.table(t, "checksum") {
            Some(s) => {
                self.unknown_keys(s, "checksum.", &["kind", "offset"]);
                let kind = match self.string(s, "kind", "checksum.kind") {
                    Some("sum8") => Some(ChecksumKind::Sum8),
                    Some(other) => {
                        self.err("checksum.kind", format!("unknown checksum {other:?} (expected sum8)"));
                        None
                    }
                    None => None,
                };
                let kind = self.required(kind, s, "kind", "checksum.kind");
                let offset = self.int(s, "offset", "checksum.offset", 0, 4095);
                let offset = self.required(offset, s, "offset", "checksum.offset");
                if let Some(o) = offset {
                    self.fits("checksum.offset", o as usize, 1, report_len, has_id);
                }
                match (kind, offset) {
                    (Some(kind), Some(o)) => Some(Checksum { kind, offset: o as usize }),
                    _ => None,
                }
            }
            None => None,
        };
        let status_offset = match self.table(t, "status") {
            Some(s) => {
                self.unknown_keys(s, "status.", &["offset"]);
                let offset = self.int(s, "offset", "status.offset", 0, 4095);
                let offset = self.required(offset, s, "offset", "status.offset");
                if let Some(o) = offset {
                    self.fits("status.offset", o as usize, 1, report_len, has_id);
                }
                offset.map(|o| o as usize)
            }
            None => None,
        };

        let channels = self.channels(t, report_len, has_id);

        if self.problems.is_empty() {
            // Everything required was present, or a problem was recorded.
            if let (Some(name), Some(report_len)) = (name, report_len) {
                return Ok(DeviceProfile {
                    name,
                    vendor_id,
                    product_id,
                    path,
                    report_id,
                    report_len,
                    sequence,
                    device_time,
                    checksum,
                    status_offset,
                    channels,
                });
            }
        }
        Err(ProfileError::Invalid(self.problems))
    }

    fn channels(&mut self, t: &toml::Table, len: Option<usize>, has_id: bool) -> Vec<Channel> {
        let mut out: Vec<Channel> = Vec::new();
        let items = match t.get("channel") {
            Some(toml::Value::Array(a)) => a.as_slice(),
            Some(other) => {
                self.err(
                    "channel",
                    format!("expected an array of tables ([[channel]]), got {}", other.type_str()),
                );
                &[]
            }
            None => &[],
        };
        let mut seen: Vec<ChannelId> = Vec::new();
        for (i, item) in items.iter().enumerate() {
            let p = |k: &str| format!("channel[{i}].{k}");
            let Some(c) = item.as_table() else {
                self.err(format!("channel[{i}]"), "expected a table");
                continue;
            };
            self.unknown_keys(c, &format!("channel[{i}]."), CHANNEL_KEYS);
            let id = match self.string(c, "name", &p("name")) {
                Some(s) => match ChannelId::parse(s) {
                    Some(id) if seen.contains(&id) => {
                        self.err(p("name"), format!("{s} is defined more than once"));
                        None
                    }
                    Some(id) => {
                        seen.push(id);
                        Some(id)
                    }
                    None => {
                        self.err(
                            p("name"),
                            format!(
                                "unknown channel {s:?} (expected one of {})",
                                ChannelId::ALL.map(|c| c.as_str()).join(", ")
                            ),
                        );
                        None
                    }
                },
                None => None,
            };
            let id = self.required(id, c, "name", &p("name"));
            let offset = self.int(c, "offset", &p("offset"), 0, 4095).map(|o| o as usize);
            let offset = self.required(offset, c, "offset", &p("offset"));
            let ty = self.field_type(c, &p("type"));
            let ty = self.required(ty, c, "type", &p("type"));
            if let (Some(o), Some(ty)) = (offset, ty) {
                self.fits(&p("offset"), o, ty.size(), len, has_id);
            }
            let scale = match self.float(c, "scale", &p("scale")) {
                Some(0.0) => {
                    self.err(p("scale"), "must not be zero");
                    None
                }
                Some(s) => Some(s),
                None if c.contains_key("scale") => None,
                None => Some(1.0),
            };
            let unit = match self.string(c, "unit", &p("unit")) {
                Some("deg") => Some(AngleUnit::Deg),
                Some("rad") => Some(AngleUnit::Rad),
                Some(other) => {
                    self.err(p("unit"), format!("unknown unit {other:?} (expected deg or rad)"));
                    None
                }
                None => None,
            };
            let unit = self.required(unit, c, "unit", &p("unit"));
            let min = self.float(c, "min", &p("min"));
            let min = self.required(min, c, "min", &p("min"));
            let max = self.float(c, "max", &p("max"));
            let max = self.required(max, c, "max", &p("max"));
            if let (Some(lo), Some(hi)) = (min, max)
                && lo >= hi
            {
                self.err(p("max"), format!("{hi} must be greater than min {lo}"));
            }
            // A wrist or thumb channel may not let through what no hand source accepts.
            if let (Some(id), Some(unit)) = (id, unit)
                && id.is_hand_angle()
            {
                let limit = frond_motion::plausible::MAX_HAND_ANGLE_DEG as f64;
                for (key, v) in [("min", min), ("max", max)] {
                    let Some(v) = v else { continue };
                    let (deg, name) = match unit {
                        AngleUnit::Deg => (v, "degrees"),
                        AngleUnit::Rad => (v.to_degrees(), "radians"),
                    };
                    if deg.is_nan() || deg.abs() > limit {
                        self.err(
                            p(key),
                            format!("{v} {name} is beyond the hand angle limit of ±{limit} degrees"),
                        );
                    }
                }
            }
            if let (Some(id), Some(offset), Some(ty), Some(scale), Some(unit), Some(min), Some(max)) =
                (id, offset, ty, scale, unit, min, max)
            {
                out.push(Channel { id, offset, ty, scale, divisor: 1.0 / scale, unit, min, max });
            }
        }
        for id in ChannelId::ALL.into_iter().filter(|c| c.required()) {
            if !seen.contains(&id) {
                self.err("channel", format!("required channel {id} is missing"));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_device_name_is_printable_and_bounded() {
        let with_name = |name: &str| {
            FROND_GLOVE_TOML.replacen(
                &format!("name = {}", toml::Value::from(DeviceProfile::frond_glove().name)),
                &format!("name = {}", toml::Value::from(name)),
                1,
            )
        };
        assert_eq!(DeviceProfile::from_toml_str(&with_name("glove 2")).unwrap().name, "glove 2");
        for (name, want) in [
            (
                "glove\nPROBLEM      none",
                "name: contains the control character '\\n'; a name must be printable",
            ),
            ("a\u{1b}[2K", "name: contains the control character '\\u{1b}'"),
            (" ", "name: must not be empty"),
        ] {
            let e = DeviceProfile::from_toml_str(&with_name(name)).unwrap_err().to_string();
            assert!(e.contains(want), "{name:?}: {e}");
        }
        let e = DeviceProfile::from_toml_str(&with_name(&"x".repeat(129))).unwrap_err().to_string();
        assert!(e.contains("name: is 129 bytes; the limit is 128"), "{e}");
    }

    #[test]
    fn reference_glove_profile_parses() {
        let p = DeviceProfile::frond_glove();
        assert_eq!(p.vendor_id, Some(0x1209));
        assert_eq!(p.product_id, Some(0xF0D1));
        assert_eq!(p.report_id, Some(1));
        assert_eq!(p.report_len, 64);
        assert_eq!(p.channels.len(), 10);
        let thumb_g3 = p.channel(ChannelId::ThumbG3).unwrap();
        assert_eq!(thumb_g3.offset, 19);
        assert_eq!(thumb_g3.divisor, 100.0);
        assert_eq!(p.channel(ChannelId::FlexLittle).unwrap().offset, 27);
        assert_eq!(p.status_offset, Some(29));
        assert_eq!(p.checksum, Some(Checksum { kind: ChecksumKind::Sum8, offset: 63 }));
    }

    /// Issue 14, point 11: a wrist or thumb channel may not pass angles that no hand source
    /// accepts (`frond_motion::plausible::MAX_HAND_ANGLE_DEG`); a flex channel is no hand angle.
    #[test]
    fn hand_angle_channels_stay_within_the_hand_limits() {
        let wide = FROND_GLOVE_TOML.replacen("min = -180.0", "min = -1000.0", 1).replacen(
            "unit = \"deg\"\nmin = -180.0\nmax = 180.0",
            "unit = \"rad\"\nmin = -3.0\nmax = 7.0",
            1,
        );
        let e = DeviceProfile::from_toml_str(&wide).unwrap_err().to_string();
        assert!(
            e.contains("channel[0].min: -1000 degrees is beyond the hand angle limit of ±360 degrees"),
            "{e}"
        );
        assert!(
            e.contains("channel[1].max: 7 radians is beyond the hand angle limit of ±360 degrees"),
            "{e}"
        );
        assert!(!e.contains("channel[1].min"), "-3 rad is within 360 degrees: {e}");
        // The flex channels (from channel[6]) are not bounded by the hand limits.
        let flex = FROND_GLOVE_TOML.replace(
            "min = -180.0\nmax = 180.0\n\n[[channel]]\nname = \"flex_middle\"",
            "min = -1000.0\nmax = 180.0\n\n[[channel]]\nname = \"flex_middle\"",
        );
        assert_ne!(flex, FROND_GLOVE_TOML);
        assert!(DeviceProfile::from_toml_str(&flex).is_ok());
    }
}
