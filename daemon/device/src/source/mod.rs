//! Hand sources: where the realtime loop gets [`DeviceSample`](crate::DeviceSample)s from.
//!
//! Every backend is one module here with its parse entry (a configuration's kind text to a
//! [`SourceSpec`]) and its source type (which implements [`HandSource`]); [`registry::BACKENDS`]
//! lists the parse entries, and its order is the order help and errors name the kinds in.
//! The virtual glove's kinds (`auto`, `virtual`, `in-process`) parse here too ([`glove_kinds`]);
//! the glove itself is the `frond-vhid` crate, which the daemon opens. [`webcam`] is a camera's
//! hands through a landmark model (issue 47).

pub mod glove_kinds;
mod hand;
mod hid;
pub mod leap;
mod osc;
#[cfg(test)]
mod osc_agreement;
mod osc_wire;
pub mod registry;
mod replay;
mod spec;
pub mod webcam;

pub use frond_protocol::SourceKind;
pub use hand::{HandSource, SourceError};
pub use hid::HidSource;
pub use leap::{LeapAddress, LeapAddressError, LeapSource};
pub use osc::{OSC_HAND_ADDRESS, OscHandSource, decode_hand_packet};
pub use registry::{BACKENDS, kind_names, parse_spec};
pub use replay::ReplaySource;
pub use spec::{Backend, SourceSpec, SpecError, SpecInput};
pub use webcam::{WebcamAddress, WebcamAddressError, WebcamSource};
