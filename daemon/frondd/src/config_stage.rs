//! The configuration of a mocap stage (issue 46): the `[triggers]` table (capture triggers to
//! follow and lead) and the `[ltc]` table (the stage's timecode), raw as read and validated into
//! [`TriggersConfig`] and [`LtcConfig`], each problem named by its key path. Split from `config`,
//! which reads and merges every table.

use std::net::{IpAddr, SocketAddr};

use serde::Deserialize;

/// The `[triggers]` table: a mocap stage's capture triggers (issue 46).
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTriggers {
    pub(crate) listen: Option<String>,
    pub(crate) allow: Option<Vec<String>>,
    pub(crate) lead: Option<String>,
    pub(crate) honour_delay: Option<bool>,
    pub(crate) timecode_fps: Option<String>,
}

/// The `[ltc]` table: the stage's timecode from LTC audio (issue 46).
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLtc {
    pub(crate) input: Option<String>,
    pub(crate) sample_rate_hz: Option<i64>,
    pub(crate) fps: Option<String>,
}

/// The `[ltc]` table, validated: where frond reads the stage's LTC from (issue 46,
/// `frond_ltc`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LtcConfig {
    /// `ltc.input`: a file or FIFO of raw mono s16le samples, a WAV file, or an ALSA capture
    /// device (`alsa:DEVICE`); `None`: no LTC.
    pub input: Option<crate::ltc_input::LtcSource>,
    /// `ltc.sample_rate_hz`: the raw samples' rate (a WAV file's header says its own).
    pub sample_rate_hz: u32,
    /// `ltc.fps`: the rate expected; LTC at another is not used. `None`: any rate.
    pub fps: Option<frond_ltc::FrameRate>,
}

impl Default for LtcConfig {
    fn default() -> Self {
        LtcConfig { input: None, sample_rate_hz: 48_000, fps: None }
    }
}

impl LtcConfig {
    pub(crate) fn validate(errors: &mut Vec<String>, raw: &RawLtc) -> LtcConfig {
        let (min, max) = (frond_ltc::MIN_SAMPLE_RATE_HZ, frond_ltc::MAX_SAMPLE_RATE_HZ);
        let sample_rate_hz =
            range(errors, "ltc.sample_rate_hz", raw.sample_rate_hz.or(Some(48_000)), min.into(), max.into());
        let fps = frame_rate(errors, "ltc.fps", raw.fps.as_deref());
        let input = raw.input.as_deref().and_then(|text| match crate::ltc_input::LtcSource::parse(text) {
            Ok(source) => Some(source),
            Err(why) => {
                errors.push(format!("ltc.input: {why}"));
                None
            }
        });
        if raw.input.is_none() && raw.fps.is_some() {
            errors.push("ltc.fps: needs ltc.input (frond reads no LTC without it)".into());
        }
        LtcConfig { input, sample_rate_hz: sample_rate_hz as u32, fps }
    }
}

/// The `[triggers]` table, validated: where frond hears a stage master's `CaptureStart` /
/// `CaptureStop` and from whom, and where it sends its own (issue 46, `frond_triggers`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TriggersConfig {
    /// `triggers.listen`: the UDP address to follow on (`0.0.0.0:30` for Vicon's broadcasts);
    /// `None`: frond does not follow.
    pub listen: Option<SocketAddr>,
    /// `triggers.allow`: the hosts followed; `None` follows any host.
    pub allow: Option<Vec<IpAddr>>,
    /// `triggers.lead`: where frond's own `record start` / `record stop` are sent
    /// (`255.255.255.255:30`, or one host); `None`: frond does not lead.
    pub lead: Option<SocketAddr>,
    /// `triggers.honour_delay`: whether a start waits for its `Delay`.
    pub honour_delay: bool,
    /// `triggers.timecode_fps`: the rate of the `TimeCode` a master's `CaptureStart` carries
    /// (Motive's, Rokoko's), which anchors the take's stage timecode when no LTC is locked; a
    /// drop-frame label (`;`) is 29.97 drop-frame whatever this says. `None`: `ltc.fps`, if set.
    pub timecode_fps: Option<frond_ltc::FrameRate>,
}

impl TriggersConfig {
    /// Whether frond follows or leads at all (and so runs the trigger thread).
    pub fn enabled(&self) -> bool {
        self.listen.is_some() || self.lead.is_some()
    }

    pub(crate) fn validate(errors: &mut Vec<String>, raw: &RawTriggers) -> TriggersConfig {
        let address = |errors: &mut Vec<String>, key: &str, text: &Option<String>| {
            let text = text.as_deref()?;
            text.parse::<SocketAddr>()
                .map_err(|_| {
                    errors.push(format!("{key}: {text:?} is not an address IP:PORT (e.g. 0.0.0.0:30)"))
                })
                .ok()
        };
        let listen = address(errors, "triggers.listen", &raw.listen);
        let lead = address(errors, "triggers.lead", &raw.lead);
        if let Some(lead) = lead
            && (lead.port() == 0 || lead.ip().is_unspecified())
        {
            errors.push(format!(
                "triggers.lead: {lead} is not a destination (a host or broadcast address, a port)"
            ));
        }
        let allow = raw.allow.as_ref().map(|hosts| {
            if hosts.is_empty() {
                errors.push("triggers.allow: lists no host (remove it to follow any host)".into());
            }
            let parsed = hosts.iter().enumerate().filter_map(|(i, h)| {
                h.parse::<IpAddr>()
                    .map_err(|_| errors.push(format!("triggers.allow[{i}]: {h:?} is not an IP address")))
                    .ok()
            });
            parsed.collect::<Vec<_>>()
        });
        if allow.is_some() && listen.is_none() {
            errors.push("triggers.allow: needs triggers.listen (frond follows no host without it)".into());
        }
        let timecode_fps = frame_rate(errors, "triggers.timecode_fps", raw.timecode_fps.as_deref());
        if timecode_fps.is_some() && listen.is_none() {
            errors.push(
                "triggers.timecode_fps: needs triggers.listen (frond follows no host without it)".into(),
            );
        }
        TriggersConfig { listen, allow, lead, honour_delay: raw.honour_delay.unwrap_or(true), timecode_fps }
    }
}

/// A frame rate key's value (one of `frond_ltc::FrameRate::ALL` as written: `24`, `25`,
/// `29.97df`, `29.97`, `30`), or its problem, named by `key`.
fn frame_rate(errors: &mut Vec<String>, key: &str, text: Option<&str>) -> Option<frond_ltc::FrameRate> {
    let text = text?;
    let rate = frond_ltc::FrameRate::ALL.into_iter().find(|r| r.to_string() == text);
    if rate.is_none() {
        let all: Vec<String> = frond_ltc::FrameRate::ALL.iter().map(ToString::to_string).collect();
        errors.push(format!("{key}: {text:?} is not one of {}", all.join(", ")));
    }
    rate
}

/// `v` (or `lo` when absent) if within `lo..=hi`; otherwise `lo`, with the problem named by
/// `key`. Shared by every table's validation (`config` uses it too).
pub(crate) fn range(errors: &mut Vec<String>, key: &str, v: Option<i64>, lo: i64, hi: i64) -> i64 {
    let v = v.unwrap_or(lo);
    if v < lo || v > hi {
        errors.push(format!("{key}: {v} is out of range {lo}..={hi}"));
        return lo;
    }
    v
}
