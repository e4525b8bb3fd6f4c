//! [`SourceSpec`]: a hand source as a configuration names it, parsed and checked, not yet
//! opened; and [`Backend`], the parse entry a backend's module registers in
//! [`BACKENDS`](super::registry::BACKENDS).

use std::path::PathBuf;

use super::leap::address::{LeapAddress, LeapAddressError};
use super::webcam::address::{WebcamAddress, WebcamAddressError};

/// Which hand source to use: what one backend's parse entry made of a kind text
/// (`frondd --source`, `[source] kind`, `[[hands]] kind`, `--hand NAME=KIND`).
///
/// A new backend adds its variant here; every `match` on it (opening it in the daemon,
/// [`SourceSpec::same_service`]) then fails to compile until it handles the new kind.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceSpec {
    /// A matching glove if present, else the virtual glove.
    Auto,
    /// The virtual glove (FUSE node, or in-process without FUSE).
    Virtual,
    /// The virtual glove in-process only.
    InProcess,
    /// A real device only.
    Hid,
    /// A JSONL hand recording.
    Replay(PathBuf),
    /// `/frond/hand` OSC messages on this UDP address.
    Osc(String),
    /// A Leap Motion / Ultraleap tracking service (`leap://HOST:PORT[?hand=left|right]`).
    Leap(LeapAddress),
    /// A camera's hands through the landmark helper (`webcam[:CAMERA_OR_FILE][?hand=left|right]`).
    Webcam(WebcamAddress),
}

impl SourceSpec {
    /// Whether two sources would read the same service for the same hand: one OSC port (equal
    /// addresses, or one of them every interface: the second could not bind, or would take the
    /// first one's datagrams), or one Leap service (host and port, letters in either case) and
    /// one chirality. Two chiralities of one Leap service are two hands, as a tracker sees them;
    /// so are the two hands of one camera (`webcam`), which share its helper.
    /// (Two hands on one hidraw node are the daemon's check: it knows their `path`s.)
    pub fn same_service(&self, other: &SourceSpec) -> bool {
        match (self, other) {
            (SourceSpec::Osc(a), SourceSpec::Osc(b)) => {
                match (a.parse::<std::net::SocketAddr>(), b.parse::<std::net::SocketAddr>()) {
                    (Ok(a), Ok(b)) => {
                        a.port() == b.port()
                            && (a.ip() == b.ip() || a.ip().is_unspecified() || b.ip().is_unspecified())
                    }
                    _ => a == b,
                }
            }
            (SourceSpec::Leap(a), SourceSpec::Leap(b)) => {
                a.hand == b.hand && a.host_port.eq_ignore_ascii_case(&b.host_port)
            }
            (SourceSpec::Webcam(a), SourceSpec::Webcam(b)) => a.hand == b.hand && a.input == b.input,
            _ => false,
        }
    }
}

/// What a parse entry may read beside the kind text, and the keys its errors name.
#[derive(Debug, Clone, Copy)]
pub struct SpecInput<'a> {
    /// The key the kind was given under (`source.kind`, `hands[1].kind`).
    pub key: &'a str,
    /// The replay file, when one was given (`source.replay`, `hands[1].replay`).
    pub replay: Option<&'a str>,
    /// The key of the replay file.
    pub replay_key: &'a str,
}

/// One registered hand source: how configurations write it and its parse entry.
#[derive(Debug, Clone, Copy)]
pub struct Backend {
    /// The kind as help and errors write it: `hid`, `osc://IP:PORT`.
    pub syntax: &'static str,
    /// The parse entry: `None` when `kind` is not this backend's; otherwise the spec, or the
    /// problem, whose text is one line naming [`SpecInput::key`] (or the replay key).
    pub parse: fn(kind: &str, input: &SpecInput<'_>) -> Option<Result<SourceSpec, SpecError>>,
}

/// A source kind a configuration gives that no backend takes, or takes but refuses. Each
/// names the key it was given under and what was typed; the text is one line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SpecError {
    /// A kind no backend takes; the text lists the kinds ([`kind_names`](super::kind_names)).
    #[error("{key}: {kind:?} is not one of {}", super::registry::kind_names())]
    UnknownKind {
        /// The key the kind was given under.
        key: String,
        /// The kind given.
        kind: String,
    },
    /// `replay` without its file.
    #[error("{replay_key}: required when {key} = \"replay\"")]
    NoReplayFile {
        /// The key the file belongs under.
        replay_key: String,
        /// The key the kind was given under.
        key: String,
    },
    /// `osc://` followed by no `IP:PORT`.
    #[error("{key}: {kind:?}: expected osc://IP:PORT, e.g. osc://127.0.0.1:9001")]
    BadOsc {
        /// The key the kind was given under.
        key: String,
        /// The kind given.
        kind: String,
    },
    /// `leap://` followed by no valid address. The address's problem is part of the text (not a
    /// `source`, so a report printing the chain does not say it twice).
    #[error("{key}: {problem}")]
    BadLeap {
        /// The key the kind was given under.
        key: String,
        /// What is wrong with the address (it names the text given).
        problem: LeapAddressError,
    },
    /// `webcam` followed by no valid camera or options.
    #[error("{key}: {problem}")]
    BadWebcam {
        /// The key the kind was given under.
        key: String,
        /// What is wrong with the address (it names the text given).
        problem: WebcamAddressError,
    },
}
