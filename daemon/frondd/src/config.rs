//! Daemon configuration: embedded defaults, an optional TOML file, then command-line overrides,
//! validated into a typed [`Config`] that reports every problem with its key path.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;

pub use crate::config_stage::{LtcConfig, TriggersConfig};
use crate::config_stage::{RawLtc, RawTriggers, range};

/// Largest configuration file read, bytes.
pub const MAX_CONFIG_FILE_BYTES: u64 = 1 << 20;

/// Every problem found in a configuration, each naming its key path (`source.kind: ...`) or its
/// origin (the file, the flag), so that all of them can be fixed in one go.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}", .problems.join("; "))]
pub struct ConfigError {
    /// One line per problem.
    pub problems: Vec<String>,
}

impl ConfigError {
    fn one(problem: String) -> Self {
        ConfigError { problems: vec![problem] }
    }
}

/// The embedded default configuration (documented, shipped in the binary).
pub const DEFAULT_CONFIG: &str = include_str!("default-config.toml");

/// Configuration as written in TOML (every field optional so a file may set only some).
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawConfig {
    tick_rate_hz: Option<i64>,
    rig: Option<String>,
    calibration: Option<String>,
    filter: Option<String>,
    #[serde(default)]
    source: RawSource,
    #[serde(default)]
    publisher: RawPublisher,
    #[serde(default)]
    recorder: RawRecorder,
    #[serde(default)]
    realtime: RawRealtime,
    #[serde(default)]
    control: RawControl,
    #[serde(default)]
    triggers: RawTriggers,
    #[serde(default)]
    ltc: RawLtc,
    /// Several hand sources; absent = the one of `[source]`.
    hands: Option<Vec<RawHand>>,
}

/// What is wrong with a `--hand` flag's text (before its values are validated with the rest of
/// the configuration).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum HandFlagError {
    /// No `=` between the hand's name and its kind.
    #[error("{flag:?}: expected NAME=KIND[,key=value...], e.g. right=hid:/dev/hidraw4,element=leaf")]
    NoKind { flag: String },
    /// A part after the kind without `=`.
    #[error("{flag:?}: {part:?} is not key=value")]
    NotKeyValue { flag: String, part: String },
    /// A key the flag does not take.
    #[error("{flag:?}: unknown key {key:?} (expected element, rig, calibration, profile, path)")]
    UnknownKey { flag: String, key: String },
}

/// One `[[hands]]` table (or one `--hand` flag).
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawHand {
    name: Option<String>,
    kind: Option<String>,
    profile: Option<String>,
    path: Option<String>,
    replay: Option<String>,
    rig: Option<String>,
    calibration: Option<String>,
    element: Option<String>,
}

impl RawHand {
    /// Parses a `--hand` flag: `NAME=KIND[,key=value...]`, where KIND is a source kind
    /// (`auto`, `virtual`, `in-process`, `hid`, `hid:PATH`, `replay:PATH`, `osc://IP:PORT`,
    /// `leap://HOST:PORT[?hand=left|right]`, `webcam[:DEVICE][?hand=left|right]`) and
    /// the keys are `element`, `rig`, `calibration`, `profile` and `path`.
    pub fn parse_flag(flag: &str) -> Result<RawHand, ConfigError> {
        Self::parse_flag_text(flag).map_err(|e| ConfigError::one(e.to_string()))
    }

    fn parse_flag_text(flag: &str) -> Result<RawHand, HandFlagError> {
        let (name, rest) =
            flag.split_once('=').ok_or_else(|| HandFlagError::NoKind { flag: flag.to_string() })?;
        let mut parts = rest.split(',');
        let kind = parts.next().unwrap_or_default();
        let mut hand = RawHand { name: Some(name.to_string()), ..Default::default() };
        if let Some(path) = kind.strip_prefix("hid:") {
            hand.kind = Some("hid".into());
            hand.path = Some(path.to_string());
        } else if let Some(path) = kind.strip_prefix("replay:") {
            hand.kind = Some("replay".into());
            hand.replay = Some(path.to_string());
        } else {
            hand.kind = Some(kind.to_string());
        }
        for part in parts {
            let (key, value) = part.split_once('=').ok_or_else(|| HandFlagError::NotKeyValue {
                flag: flag.to_string(),
                part: part.to_string(),
            })?;
            let slot = match key {
                "element" => &mut hand.element,
                "rig" => &mut hand.rig,
                "calibration" => &mut hand.calibration,
                "profile" => &mut hand.profile,
                "path" => &mut hand.path,
                other => {
                    return Err(HandFlagError::UnknownKey { flag: flag.to_string(), key: other.to_string() });
                }
            };
            *slot = Some(value.to_string());
        }
        Ok(hand)
    }
}

#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawControl {
    allowed_uids: Option<Vec<i64>>,
    allowed_gids: Option<Vec<i64>>,
}

#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSource {
    kind: Option<String>,
    profile: Option<String>,
    path: Option<String>,
    replay: Option<String>,
    stall_ms: Option<i64>,
    virtual_rate_hz: Option<i64>,
    virtual_clock: Option<String>,
}

#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPublisher {
    queue_frames: Option<i64>,
    max_subscribers: Option<i64>,
    write_timeout_ms: Option<i64>,
}

#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRecorder {
    fsync_interval_ms: Option<i64>,
}

#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRealtime {
    priority: Option<i64>,
    lock_memory: Option<bool>,
    cpu: Option<i64>,
}

impl RawConfig {
    /// Parses one TOML document; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<RawConfig, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::one(format!("{origin}: {e}")))
    }

    /// Overlays `other` onto `self`: every key `other` sets wins.
    pub fn overlay(mut self, other: RawConfig) -> RawConfig {
        fn pick<T>(a: &mut Option<T>, b: Option<T>) {
            if b.is_some() {
                *a = b;
            }
        }
        pick(&mut self.tick_rate_hz, other.tick_rate_hz);
        pick(&mut self.rig, other.rig);
        pick(&mut self.calibration, other.calibration);
        pick(&mut self.filter, other.filter);
        pick(&mut self.source.kind, other.source.kind);
        pick(&mut self.source.profile, other.source.profile);
        pick(&mut self.source.path, other.source.path);
        pick(&mut self.source.replay, other.source.replay);
        pick(&mut self.source.stall_ms, other.source.stall_ms);
        pick(&mut self.source.virtual_rate_hz, other.source.virtual_rate_hz);
        pick(&mut self.source.virtual_clock, other.source.virtual_clock);
        pick(&mut self.publisher.queue_frames, other.publisher.queue_frames);
        pick(&mut self.publisher.max_subscribers, other.publisher.max_subscribers);
        pick(&mut self.publisher.write_timeout_ms, other.publisher.write_timeout_ms);
        pick(&mut self.recorder.fsync_interval_ms, other.recorder.fsync_interval_ms);
        pick(&mut self.realtime.priority, other.realtime.priority);
        pick(&mut self.realtime.lock_memory, other.realtime.lock_memory);
        pick(&mut self.realtime.cpu, other.realtime.cpu);
        pick(&mut self.control.allowed_uids, other.control.allowed_uids);
        pick(&mut self.control.allowed_gids, other.control.allowed_gids);
        pick(&mut self.triggers.listen, other.triggers.listen);
        pick(&mut self.triggers.allow, other.triggers.allow);
        pick(&mut self.triggers.lead, other.triggers.lead);
        pick(&mut self.triggers.honour_delay, other.triggers.honour_delay);
        pick(&mut self.triggers.timecode_fps, other.triggers.timecode_fps);
        pick(&mut self.ltc.input, other.ltc.input);
        pick(&mut self.ltc.sample_rate_hz, other.ltc.sample_rate_hz);
        pick(&mut self.ltc.fps, other.ltc.fps);
        pick(&mut self.hands, other.hands);
        self
    }

    /// The command line's overrides, as the keys they set.
    pub fn from_overrides(o: Overrides) -> RawConfig {
        RawConfig {
            tick_rate_hz: o.rate.map(i64::from),
            rig: o.rig,
            calibration: o.calibration,
            filter: o.filter,
            source: RawSource {
                kind: o.source,
                profile: o.profile,
                path: o.device,
                replay: o.replay,
                ..Default::default()
            },
            triggers: RawTriggers {
                listen: o.triggers,
                allow: (!o.trigger_allow.is_empty()).then_some(o.trigger_allow),
                lead: o.trigger_lead,
                ..Default::default()
            },
            ltc: RawLtc { input: o.ltc, ..Default::default() },
            ..Default::default()
        }
    }

    /// The hands of `--hand` flags (replacing any `[[hands]]`), if any were given.
    pub fn with_hands(mut self, hands: Vec<RawHand>) -> RawConfig {
        if !hands.is_empty() {
            self.hands = Some(hands);
        }
        self
    }
}

/// What frondd's command line sets over the configuration file; `None` leaves the file's key.
#[derive(Debug, Default, Clone)]
pub struct Overrides {
    /// `--rate`: `tick_rate_hz`.
    pub rate: Option<u32>,
    /// `--rig`: `rig`.
    pub rig: Option<String>,
    /// `--calibration`: `calibration`.
    pub calibration: Option<String>,
    /// `--filter`: `filter`.
    pub filter: Option<String>,
    /// `--source` (or the kind `--device` and `--replay` imply): `source.kind`.
    pub source: Option<String>,
    /// `--profile`: `source.profile`.
    pub profile: Option<String>,
    /// `--device`: `source.path`.
    pub device: Option<String>,
    /// `--replay`: `source.replay`.
    pub replay: Option<String>,
    /// `--triggers`: `triggers.listen`.
    pub triggers: Option<String>,
    /// `--trigger-allow` (repeated): `triggers.allow`; empty leaves the file's list.
    pub trigger_allow: Vec<String>,
    /// `--trigger-lead`: `triggers.lead`.
    pub trigger_lead: Option<String>,
    /// `--ltc`: `ltc.input`.
    pub ltc: Option<String>,
}

/// Which hand source to use: the hand sources' own parsed form, each kind parsed by its backend
/// in `frond_device::source` (one table, [`frond_device::BACKENDS`]).
pub use frond_device::SourceSpec as SourceChoice;

/// Validated configuration.
#[derive(Debug, Clone)]
pub struct Config {
    /// Loop rate.
    pub tick_rate_hz: u32,
    /// Rig: embedded name or path.
    pub rig: String,
    /// Calibration file.
    pub calibration: Option<PathBuf>,
    /// Filter spec overriding the rig's.
    pub filter: Option<String>,
    /// The hand sources, at least one and at most [`MAX_HANDS`]: the one of `[source]`
    /// (named `hand`) unless `[[hands]]` or `--hand` lists several.
    pub hands: Vec<HandConfig>,
    /// Stall detection window.
    pub stall: Duration,
    /// Rate of the built-in sway.
    pub virtual_rate_hz: u32,
    /// Device clock of the built-in virtual glove (`monotonic` lets subscribers measure
    /// glove-to-receipt latency).
    pub virtual_clock: frond_vhid::DeviceClock,
    /// Subscriber queue length.
    pub queue_frames: usize,
    /// Subscriber limit.
    pub max_subscribers: usize,
    /// Subscriber write timeout.
    pub write_timeout: Duration,
    /// fdatasync interval of takes.
    pub fsync_interval: Duration,
    /// SCHED_FIFO priority (0 = none).
    pub rt_priority: u8,
    /// mlockall.
    pub lock_memory: bool,
    /// CPU the loop thread is pinned to, if any.
    pub rt_cpu: Option<usize>,
    /// Users (besides root and the daemon's own user) allowed on the control socket.
    pub allowed_uids: Vec<u32>,
    /// Groups allowed on the control socket (primary or supplementary group of the client).
    pub allowed_gids: Vec<u32>,
    /// A mocap stage's capture triggers: follow, lead, or neither.
    pub triggers: TriggersConfig,
    /// The stage's timecode from LTC audio, if an input is given.
    pub ltc: LtcConfig,
}

/// Most hand sources (the engine's limit).
pub use crate::engine::MAX_HANDS;

/// Name of the hand when only `[source]` configures one.
pub const SINGLE_HAND: &str = "hand";

/// One hand source, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct HandConfig {
    /// Its name (in status, the element table and logs).
    pub name: String,
    /// Where its reports come from.
    pub source: SourceChoice,
    /// Device profile file (None = embedded reference glove).
    pub profile: Option<PathBuf>,
    /// Device node path.
    pub device_path: Option<PathBuf>,
    /// A rig of its own (embedded name or path); `None` = the daemon's rig, which `frond rig set`
    /// and SIGHUP change for it too.
    pub rig: Option<String>,
    /// A calibration of its own; `None` = the daemon's (or, with a rig of its own, neutral).
    pub calibration: Option<PathBuf>,
    /// The rig element it drives: a secondary element's name (`leaf`), or `None` for the
    /// global element.
    pub element: Option<String>,
}

impl HandConfig {
    /// Whether the daemon's rig, calibration and filter apply to it.
    pub fn follows_setup(&self) -> bool {
        self.rig.is_none() && self.calibration.is_none()
    }
}

/// Parses a source kind (`key` names it in errors) with the backend that takes it.
fn source_choice(
    errors: &mut Vec<String>,
    key: &str,
    kind: &str,
    replay: Option<&str>,
    replay_key: &str,
) -> SourceChoice {
    let input = frond_device::SpecInput { key, replay, replay_key };
    frond_device::parse_spec(kind, &input).unwrap_or_else(|e| {
        errors.push(e.to_string());
        SourceChoice::Auto
    })
}

/// Validates the `[[hands]]` list: names, kinds, and no two hands on one device or address.
fn validate_hands(errors: &mut Vec<String>, raw: Vec<RawHand>) -> Vec<HandConfig> {
    if raw.is_empty() {
        errors.push("hands: lists no hand (remove it to use [source])".into());
    }
    if raw.len() > MAX_HANDS {
        errors.push(format!("hands: {} hands; the limit is {MAX_HANDS}", raw.len()));
    }
    let mut hands: Vec<HandConfig> = Vec::new();
    // Whether each hand's kind parsed (only those are compared for shared devices).
    let mut valid_kind: Vec<bool> = Vec::new();
    for (i, h) in raw.into_iter().take(MAX_HANDS).enumerate() {
        let key = |k: &str| format!("hands[{i}].{k}");
        let name = h.name.unwrap_or_default();
        if !crate::stage::registry::is_plain_name(&name) {
            errors.push(format!("{}: {name:?}: 1 to 32 letters, digits, '_' or '-'", key("name")));
        } else if let Some(j) = hands.iter().position(|o| o.name == name) {
            errors.push(format!("{}: {name:?} is also the name of hands[{j}]", key("name")));
        }
        let errors_before = errors.len();
        let source = match h.kind.as_deref() {
            Some(kind) => source_choice(errors, &key("kind"), kind, h.replay.as_deref(), &key("replay")),
            None => {
                errors.push(format!("{}: required ({})", key("kind"), frond_device::kind_names()));
                SourceChoice::Auto
            }
        };
        if matches!(h.element.as_deref(), Some("")) {
            errors.push(format!(
                "{}: must name a secondary element of the rig, or be left out for the global element",
                key("element")
            ));
        }
        let hand = HandConfig {
            name,
            source,
            profile: h.profile.map(PathBuf::from),
            device_path: h.path.map(PathBuf::from),
            rig: h.rig,
            calibration: h.calibration.map(PathBuf::from),
            element: h.element.filter(|e| e != "global"),
        };
        let kind_ok = errors.len() == errors_before;
        valid_kind.push(kind_ok);
        let comparable = hands.iter().enumerate().filter(|&(j, _)| kind_ok && valid_kind[j]);
        for (j, other) in comparable {
            let same_device = hand.device_path.is_some() && hand.device_path == other.device_path;
            let same_address = hand.source.same_service(&other.source);
            let both_search = matches!(hand.source, SourceChoice::Auto | SourceChoice::Hid)
                && matches!(other.source, SourceChoice::Auto | SourceChoice::Hid)
                && hand.device_path.is_none()
                && other.device_path.is_none();
            if same_device || same_address || both_search {
                errors.push(format!(
                    "{}: hands[{j}] ({:?}) reads the same device or address; give each hand its own `path` or address",
                    key("kind"),
                    other.name
                ));
                break;
            }
        }
        hands.push(hand);
    }
    hands
}

/// The one hand of `[source]`, named [`SINGLE_HAND`], when no `[[hands]]` lists several.
fn single_hand(errors: &mut Vec<String>, raw: &RawSource) -> HandConfig {
    let kind = raw.kind.as_deref().unwrap_or("auto");
    let source = source_choice(errors, "source.kind", kind, raw.replay.as_deref(), "source.replay");
    HandConfig {
        name: SINGLE_HAND.into(),
        source,
        profile: raw.profile.as_ref().map(PathBuf::from),
        device_path: raw.path.as_ref().map(PathBuf::from),
        rig: None,
        calibration: None,
        element: None,
    }
}

/// `source.virtual_clock`: the built-in virtual glove's device clock.
fn virtual_clock(errors: &mut Vec<String>, text: Option<&str>) -> frond_vhid::DeviceClock {
    match text {
        None | Some("schedule") => frond_vhid::DeviceClock::Schedule,
        Some("monotonic") => frond_vhid::DeviceClock::Monotonic,
        Some(other) => {
            errors.push(format!("source.virtual_clock: {other:?} is not one of schedule, monotonic"));
            frond_vhid::DeviceClock::Schedule
        }
    }
}

/// The `[publisher]` table, validated: queue length, subscriber limit, write timeout.
struct PublisherLimits {
    queue_frames: usize,
    max_subscribers: usize,
    write_timeout: Duration,
}

impl PublisherLimits {
    fn validate(errors: &mut Vec<String>, raw: &RawPublisher) -> PublisherLimits {
        let queue_frames =
            range(errors, "publisher.queue_frames", raw.queue_frames.or(Some(1024)), 2, 1 << 20);
        let max_subscribers = range(
            errors,
            "publisher.max_subscribers",
            raw.max_subscribers.or(Some(64)),
            1,
            crate::engine::MAX_SUBSCRIBERS as i64,
        );
        let write_timeout_ms =
            range(errors, "publisher.write_timeout_ms", raw.write_timeout_ms.or(Some(2000)), 10, 600_000);
        PublisherLimits {
            queue_frames: queue_frames as usize,
            max_subscribers: max_subscribers as usize,
            write_timeout: Duration::from_millis(write_timeout_ms as u64),
        }
    }
}

/// `control.allowed_uids` or `control.allowed_gids` (`key`): user or group ids.
fn ids(errors: &mut Vec<String>, key: &str, v: Option<&[i64]>) -> Vec<u32> {
    let mut out = Vec::new();
    for (i, &id) in v.unwrap_or_default().iter().enumerate() {
        match u32::try_from(id) {
            Ok(id) => out.push(id),
            Err(_) => errors.push(format!("{key}[{i}]: {id} is not a valid id")),
        }
    }
    out
}

impl Config {
    /// Validates a merged raw configuration, reporting every problem at once, in the order of
    /// the keys: the loop and rig, the hands, the filter, `[source]`, `[publisher]`,
    /// `[recorder]`, `[realtime]`, `[control]`, `[triggers]`, `[ltc]`.
    pub fn validate(raw: RawConfig) -> Result<Config, ConfigError> {
        let mut errors = Vec::new();
        let tick_rate_hz = range(&mut errors, "tick_rate_hz", raw.tick_rate_hz, 30, 8000) as u32;
        let rig = raw.rig.unwrap_or_else(|| "grass".into());
        if rig.trim().is_empty() {
            errors.push("rig: must name an embedded rig or a file".into());
        }
        let hands = match raw.hands {
            Some(list) => validate_hands(&mut errors, list),
            None => vec![single_hand(&mut errors, &raw.source)],
        };
        if let Some(filter) = &raw.filter
            && let Err(e) = filter.parse::<frond_motion::FilterSpec>()
        {
            errors.push(format!("filter: {e}"));
        }
        let stall_ms = range(&mut errors, "source.stall_ms", raw.source.stall_ms.or(Some(250)), 10, 60_000);
        let virtual_rate_hz =
            range(&mut errors, "source.virtual_rate_hz", raw.source.virtual_rate_hz.or(Some(1000)), 1, 8000);
        let virtual_clock = virtual_clock(&mut errors, raw.source.virtual_clock.as_deref());
        let publisher = PublisherLimits::validate(&mut errors, &raw.publisher);
        let fsync_ms = range(
            &mut errors,
            "recorder.fsync_interval_ms",
            raw.recorder.fsync_interval_ms.or(Some(1000)),
            10,
            1000,
        );
        let rt_cpu = range(&mut errors, "realtime.cpu", raw.realtime.cpu.or(Some(-1)), -1, 1023);
        let rt_priority =
            range(&mut errors, "realtime.priority", raw.realtime.priority.or(Some(0)), 0, 99) as u8;
        let allowed_uids = ids(&mut errors, "control.allowed_uids", raw.control.allowed_uids.as_deref());
        let allowed_gids = ids(&mut errors, "control.allowed_gids", raw.control.allowed_gids.as_deref());
        let triggers = TriggersConfig::validate(&mut errors, &raw.triggers);
        let ltc = LtcConfig::validate(&mut errors, &raw.ltc);
        if !errors.is_empty() {
            return Err(ConfigError { problems: errors });
        }
        Ok(Config {
            tick_rate_hz,
            rig,
            calibration: raw.calibration.map(PathBuf::from),
            filter: raw.filter,
            hands,
            stall: Duration::from_millis(stall_ms as u64),
            virtual_rate_hz: virtual_rate_hz as u32,
            virtual_clock,
            queue_frames: publisher.queue_frames,
            max_subscribers: publisher.max_subscribers,
            write_timeout: publisher.write_timeout,
            fsync_interval: Duration::from_millis(fsync_ms as u64),
            rt_priority,
            lock_memory: raw.realtime.lock_memory.unwrap_or(false),
            rt_cpu: usize::try_from(rt_cpu).ok(),
            allowed_uids,
            allowed_gids,
            triggers,
            ltc,
        })
    }

    /// Loads embedded defaults, then `file` if given, then `overrides`.
    /// The file is read only if it is a regular file of at most [`MAX_CONFIG_FILE_BYTES`].
    pub fn load(file: Option<&Path>, overrides: RawConfig) -> Result<Config, ConfigError> {
        let mut raw = RawConfig::parse(DEFAULT_CONFIG, "embedded default config")?;
        if let Some(path) = file {
            let text = frond_formats::rig_files::read_small_text(path, MAX_CONFIG_FILE_BYTES)
                .map_err(|e| ConfigError::one(format!("cannot read the config: {e}")))?;
            raw = raw.overlay(RawConfig::parse(&text, &path.display().to_string())?);
        }
        Config::validate(raw.overlay(overrides))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ltc_input::LtcSource;

    #[test]
    fn embedded_default_is_valid() {
        let c = Config::load(None, RawConfig::default()).expect("default config validates");
        assert_eq!(c.tick_rate_hz, 1000);
        assert_eq!(c.hands.len(), 1);
        assert_eq!(c.hands[0].source, SourceChoice::Auto);
        assert_eq!(c.hands[0].name, "hand");
        assert_eq!(c.rig, "grass");
    }

    #[test]
    fn every_problem_is_reported_with_its_path() {
        let raw = RawConfig::parse(
            "tick_rate_hz = 9000\n[source]\nkind = \"usb\"\n[publisher]\nqueue_frames = 1\n",
            "test",
        )
        .unwrap();
        let errors = Config::validate(raw).unwrap_err().problems;
        assert_eq!(errors.len(), 3, "{errors:?}");
        assert!(errors[0].starts_with("tick_rate_hz: 9000"), "{errors:?}");
        assert!(errors[1].starts_with("source.kind: \"usb\""), "{errors:?}");
        assert!(errors[2].starts_with("publisher.queue_frames: 1"), "{errors:?}");
    }

    #[test]
    fn unknown_keys_are_refused() {
        let err = RawConfig::parse("tick_rate = 10", "f.toml").unwrap_err().to_string();
        assert!(err.contains("f.toml") && err.contains("tick_rate"), "{err}");
    }

    #[test]
    fn realtime_cpu_is_optional_and_checked() {
        assert_eq!(Config::load(None, RawConfig::default()).unwrap().rt_cpu, None);
        let raw = RawConfig::parse("[realtime]\ncpu = 1\n", "t").unwrap();
        assert_eq!(Config::validate(raw).unwrap().rt_cpu, Some(1));
        let raw = RawConfig::parse("[realtime]\ncpu = -2\n", "t").unwrap();
        assert!(Config::validate(raw).unwrap_err().problems[0].starts_with("realtime.cpu: -2"));
    }

    #[test]
    fn virtual_clock_defaults_to_schedule_and_is_checked() {
        let c = Config::load(None, RawConfig::default()).unwrap();
        assert_eq!(c.virtual_clock, frond_vhid::DeviceClock::Schedule);
        let raw = RawConfig::parse("[source]\nvirtual_clock = \"monotonic\"\n", "t").unwrap();
        assert_eq!(Config::validate(raw).unwrap().virtual_clock, frond_vhid::DeviceClock::Monotonic);
        let raw = RawConfig::parse("[source]\nvirtual_clock = \"wall\"\n", "t").unwrap();
        let errors = Config::validate(raw).unwrap_err().problems;
        assert_eq!(errors, ["source.virtual_clock: \"wall\" is not one of schedule, monotonic"]);
    }

    #[test]
    fn hands_are_listed_validated_and_named_in_errors() {
        let raw = RawConfig::parse(
            "[[hands]]\nname = \"left\"\nkind = \"hid\"\npath = \"/dev/hidraw3\"\n\
             [[hands]]\nname = \"right\"\nkind = \"osc://127.0.0.1:9001\"\nelement = \"leaf\"\nrig = \"flower\"\n",
            "t",
        )
        .unwrap();
        let c = Config::validate(raw).unwrap();
        assert_eq!(c.hands.len(), 2);
        assert_eq!((c.hands[0].name.as_str(), &c.hands[0].source), ("left", &SourceChoice::Hid));
        assert_eq!(c.hands[0].device_path.as_deref(), Some(Path::new("/dev/hidraw3")));
        assert!(c.hands[0].follows_setup());
        assert_eq!(c.hands[1].source, SourceChoice::Osc("127.0.0.1:9001".into()));
        assert_eq!(c.hands[1].element.as_deref(), Some("leaf"));
        assert!(!c.hands[1].follows_setup(), "a rig of its own");

        let raw = RawConfig::parse(
            "[[hands]]\nname = \"a b\"\nkind = \"hid\"\n\
             [[hands]]\nname = \"x\"\n\
             [[hands]]\nname = \"x\"\nkind = \"usb\"\n\
             [[hands]]\nname = \"y\"\nkind = \"auto\"\n",
            "t",
        )
        .unwrap();
        let errors = Config::validate(raw).unwrap_err().problems;
        assert_eq!(
            errors,
            [
                "hands[0].name: \"a b\": 1 to 32 letters, digits, '_' or '-'",
                "hands[1].kind: required (auto, virtual, in-process, hid, replay, osc://IP:PORT, leap://HOST:PORT, webcam[:DEVICE])",
                "hands[2].name: \"x\" is also the name of hands[1]",
                "hands[2].kind: \"usb\" is not one of auto, virtual, in-process, hid, replay, osc://IP:PORT, leap://HOST:PORT, webcam[:DEVICE]",
                "hands[3].kind: hands[0] (\"a b\") reads the same device or address; give each hand its own `path` or address",
            ],
        );
        let nine: String =
            (0..9).map(|i| format!("[[hands]]\nname = \"h{i}\"\nkind = \"virtual\"\n")).collect();
        let errors = Config::validate(RawConfig::parse(&nine, "t").unwrap()).unwrap_err().problems;
        assert_eq!(errors, ["hands: 9 hands; the limit is 8"]);
    }

    /// Issue 42: two hands on one service and one chirality are refused, as two on one OSC
    /// address always were; two chiralities of one Leap service are two hands.
    #[test]
    fn two_hands_on_one_service_and_chirality_are_refused() {
        let problems = |kinds: &[&str]| {
            let text: String = kinds
                .iter()
                .enumerate()
                .map(|(i, k)| format!("[[hands]]\nname = \"h{i}\"\nkind = \"{k}\"\nelement = \"e{i}\"\n"))
                .collect();
            Config::validate(RawConfig::parse(&text, "t").unwrap()).err().map(|e| e.problems)
        };
        let refused = |kinds: &[&str]| {
            assert_eq!(
                problems(kinds),
                Some(vec![
                    "hands[1].kind: hands[0] (\"h0\") reads the same device or address; give each hand its own `path` or address"
                        .to_string()
                ]),
                "{kinds:?}"
            )
        };
        refused(&["leap://127.0.0.1:6437", "leap://127.0.0.1:6437?hand=right"]);
        refused(&["leap://Tracker:6437?hand=left", "leap://tracker:6437?hand=left"]);
        refused(&["osc://127.0.0.1:9001", "osc://0.0.0.0:9001"]);
        refused(&["osc://[::]:9001", "osc://127.0.0.1:9001"]);
        assert_eq!(problems(&["leap://127.0.0.1:6437?hand=left", "leap://127.0.0.1:6437?hand=right"]), None);
        assert_eq!(problems(&["leap://127.0.0.1:6437", "leap://127.0.0.1:6438"]), None);
        assert_eq!(problems(&["osc://127.0.0.1:9001", "osc://127.0.0.2:9001"]), None);
        assert_eq!(problems(&["osc://127.0.0.1:9001", "osc://127.0.0.1:9002"]), None);
    }

    #[test]
    fn hand_flags_parse_into_the_same_tables() {
        let h = RawHand::parse_flag("right=hid:/dev/hidraw4,element=leaf,calibration=/c.toml").unwrap();
        let c = Config::validate(RawConfig::default().with_hands(vec![h])).unwrap();
        let hand = &c.hands[0];
        assert_eq!((hand.name.as_str(), &hand.source), ("right", &SourceChoice::Hid));
        assert_eq!(hand.device_path.as_deref(), Some(Path::new("/dev/hidraw4")));
        assert_eq!(hand.element.as_deref(), Some("leaf"));
        assert_eq!(hand.calibration.as_deref(), Some(Path::new("/c.toml")));
        let h = RawHand::parse_flag("left=replay:/r.jsonl,element=global").unwrap();
        let c = Config::validate(RawConfig::default().with_hands(vec![h])).unwrap();
        assert_eq!(c.hands[0].source, SourceChoice::Replay("/r.jsonl".into()));
        assert_eq!(c.hands[0].element, None, "global is the default element");
        for (bad, why) in [
            ("left", "expected NAME=KIND"),
            ("left=hid,leaf", "\"leaf\" is not key=value"),
            ("left=hid,colour=red", "unknown key \"colour\""),
        ] {
            let e = RawHand::parse_flag(bad).unwrap_err().to_string();
            assert!(e.contains(why), "{bad}: {e}");
        }
        // No `--hand`: the one hand of [source] stays.
        let c = Config::validate(RawConfig::default().with_hands(vec![])).unwrap();
        assert_eq!(c.hands.len(), 1);
    }

    #[test]
    fn triggers_are_off_by_default_and_checked_with_their_paths() {
        let c = Config::load(None, RawConfig::default()).unwrap();
        assert_eq!(c.triggers, TriggersConfig { honour_delay: true, ..Default::default() });
        assert!(!c.triggers.enabled());
        let raw = RawConfig::parse(
            "[triggers]\nlisten = \"0.0.0.0:30\"\nallow = [\"10.0.0.5\", \"::1\"]\n\
             lead = \"255.255.255.255:30\"\nhonour_delay = false\n",
            "t",
        )
        .unwrap();
        let t = Config::validate(raw).unwrap().triggers;
        assert_eq!(t.listen, Some("0.0.0.0:30".parse().unwrap()));
        assert_eq!(t.allow, Some(vec!["10.0.0.5".parse().unwrap(), "::1".parse().unwrap()]));
        assert_eq!(t.lead, Some("255.255.255.255:30".parse().unwrap()));
        assert!(!t.honour_delay && t.enabled());
        assert_eq!(t.timecode_fps, None);
        let raw =
            RawConfig::parse("[triggers]\nlisten = \"0.0.0.0:1512\"\ntimecode_fps = \"24\"\n", "t").unwrap();
        assert_eq!(Config::validate(raw).unwrap().triggers.timecode_fps, Some(frond_ltc::FrameRate::Fps24));
        let raw = RawConfig::parse("[triggers]\ntimecode_fps = \"23.976\"\n", "t").unwrap();
        assert_eq!(
            Config::validate(raw).unwrap_err().problems,
            [
                "triggers.timecode_fps: \"23.976\" is not one of 24, 25, 29.97df, 29.97, 30",
                // Its parse failed, so only the bad value is named, not the missing listen.
            ]
        );
        let raw = RawConfig::parse("[triggers]\ntimecode_fps = \"25\"\n", "t").unwrap();
        assert_eq!(
            Config::validate(raw).unwrap_err().problems,
            ["triggers.timecode_fps: needs triggers.listen (frond follows no host without it)"]
        );
        let raw = RawConfig::parse(
            "[triggers]\nlisten = \"vicon:30\"\nallow = [\"10.0.0.5\", \"shogun\"]\nlead = \"0.0.0.0:0\"\n",
            "t",
        )
        .unwrap();
        assert_eq!(
            Config::validate(raw).unwrap_err().problems,
            [
                "triggers.listen: \"vicon:30\" is not an address IP:PORT (e.g. 0.0.0.0:30)",
                "triggers.lead: 0.0.0.0:0 is not a destination (a host or broadcast address, a port)",
                "triggers.allow[1]: \"shogun\" is not an IP address",
                "triggers.allow: needs triggers.listen (frond follows no host without it)",
            ]
        );
        let raw = RawConfig::parse("[triggers]\nlisten = \"0.0.0.0:30\"\nallow = []\n", "t").unwrap();
        assert_eq!(
            Config::validate(raw).unwrap_err().problems,
            ["triggers.allow: lists no host (remove it to follow any host)"]
        );
        let flags = Overrides {
            triggers: Some("127.0.0.1:3030".into()),
            trigger_allow: vec!["127.0.0.2".into()],
            trigger_lead: Some("127.0.0.1:3031".into()),
            ..Default::default()
        };
        let t = Config::load(None, RawConfig::from_overrides(flags)).unwrap().triggers;
        assert_eq!(t.listen, Some("127.0.0.1:3030".parse().unwrap()));
        assert_eq!(t.allow, Some(vec!["127.0.0.2".parse().unwrap()]));
        assert_eq!(t.lead, Some("127.0.0.1:3031".parse().unwrap()));
    }

    #[test]
    fn ltc_is_off_by_default_and_checked_with_its_keys() {
        let c = Config::load(None, RawConfig::default()).unwrap();
        assert_eq!(c.ltc, LtcConfig { input: None, sample_rate_hz: 48_000, fps: None });
        let raw = RawConfig::parse(
            "[ltc]\ninput = \"/run/frond/ltc.fifo\"\nsample_rate_hz = 44100\nfps = \"29.97df\"\n",
            "t",
        )
        .unwrap();
        let l = Config::validate(raw).unwrap().ltc;
        assert_eq!(l.input, Some(LtcSource::Path("/run/frond/ltc.fifo".into())));
        assert_eq!((l.sample_rate_hz, l.fps), (44_100, Some(frond_ltc::FrameRate::Fps2997Df)));
        let raw =
            RawConfig::parse("[ltc]\ninput = \" \"\nsample_rate_hz = 4000\nfps = \"29.976\"\n", "t").unwrap();
        assert_eq!(
            Config::validate(raw).unwrap_err().problems,
            [
                "ltc.sample_rate_hz: 4000 is out of range 8000..=192000",
                "ltc.fps: \"29.976\" is not one of 24, 25, 29.97df, 29.97, 30",
                "ltc.input: must name a file, a FIFO or alsa:DEVICE",
            ]
        );
        let raw = RawConfig::parse("[ltc]\nfps = \"25\"\n", "t").unwrap();
        assert_eq!(
            Config::validate(raw).unwrap_err().problems,
            ["ltc.fps: needs ltc.input (frond reads no LTC without it)"]
        );
        let flags = Overrides { ltc: Some("/tmp/ltc.raw".into()), ..Default::default() };
        let l = Config::load(None, RawConfig::from_overrides(flags)).unwrap().ltc;
        assert_eq!(l.input, Some(LtcSource::Path("/tmp/ltc.raw".into())));
        let flags = Overrides { ltc: Some("alsa:plughw:CARD=USB,DEV=0".into()), ..Default::default() };
        let l = Config::load(None, RawConfig::from_overrides(flags)).unwrap().ltc;
        assert_eq!(l.input, Some(LtcSource::Alsa("plughw:CARD=USB,DEV=0".into())));
        let raw = RawConfig::parse("[ltc]\ninput = \"alsa:\"\n", "t").unwrap();
        assert_eq!(
            Config::validate(raw).unwrap_err().problems,
            ["ltc.input: alsa: needs a device name, e.g. alsa:default or alsa:plughw:1,0"]
        );
    }

    #[test]
    fn overrides_win() {
        let c = Config::load(
            None,
            RawConfig::from_overrides(Overrides { rate: Some(500), ..Default::default() }),
        )
        .unwrap();
        assert_eq!(c.tick_rate_hz, 500);
    }
}
