//! [`SourceKind`]: what kind of hand source feeds a hand, as `frond status` reports it.
//!
//! Defined once, here, because the name crosses the wire (a status reply's
//! [`SourceStatus::kind`](crate::SourceStatus::kind)) and the daemon (which sets it), the hand
//! sources (which name themselves) and the SDK (which says how to fix one) all match on it: a
//! new kind is a new variant, and the compiler lists every `match` that must learn it.

use std::fmt;

use serde::{Deserialize, Serialize};

/// What kind of source feeds the loop (shown by `frond status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SourceKind {
    /// A kernel hidraw node (physical glove, or the virtual glove through UHID).
    Hidraw,
    /// The virtual glove served as a FUSE file that behaves as a hidraw node.
    FuseHidraw,
    /// The virtual glove's report generator running inside the daemon.
    InProcess,
    /// A JSONL hand recording played at its timestamps.
    Replay,
    /// `/frond/hand` OSC messages over UDP (webcam or phone hand trackers).
    Osc,
    /// A Leap Motion / Ultraleap tracking service's WebSocket (protocol v6).
    Leap,
    /// A camera's hands, found by a hand landmark model (`frond-hands`).
    Webcam,
}

impl SourceKind {
    /// Every kind, in the order `frond status` documents them.
    pub const ALL: [SourceKind; 7] = [
        SourceKind::Hidraw,
        SourceKind::FuseHidraw,
        SourceKind::InProcess,
        SourceKind::Replay,
        SourceKind::Osc,
        SourceKind::Leap,
        SourceKind::Webcam,
    ];

    /// Stable lower-case name (the wire form).
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Hidraw => "hidraw",
            Self::FuseHidraw => "fuse-hidraw",
            Self::InProcess => "in-process",
            Self::Replay => "replay",
            Self::Osc => "osc",
            Self::Leap => "leap",
            Self::Webcam => "webcam",
        }
    }

    /// The kind of this name, if it is one.
    pub fn from_name(name: &str) -> Option<SourceKind> {
        Self::ALL.into_iter().find(|k| k.as_str() == name)
    }
}

impl fmt::Display for SourceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The serde name and `as_str` are one name: a status reply carries what `Display` prints.
    #[test]
    fn wire_name_is_the_display_name() {
        for kind in SourceKind::ALL {
            let json = rmp_serde::to_vec(&kind).unwrap();
            let name: String = rmp_serde::from_slice(&json).unwrap();
            assert_eq!(name, kind.as_str());
            assert_eq!(SourceKind::from_name(&name), Some(kind));
            assert_eq!(rmp_serde::from_slice::<SourceKind>(&json).unwrap(), kind);
        }
        assert_eq!(SourceKind::from_name("virtual"), None);
    }
}
