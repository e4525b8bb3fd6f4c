//! The limits a stage request is held to, and why one could not be named, placed or built: enums
//! whose messages name the problem.

use frond_formats::take::TakeError;
use frond_motion::field::FieldError;
use frond_motion::looping::LoopError;
use frond_protocol::ControlErrorKind;

/// Stage slots in the loop (stages running at once).
pub const MAX_STAGES: usize = 8;
/// Longest stage name.
pub const MAX_STAGE_NAME: usize = 32;

/// Why a stage could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct BuildError {
    /// Refusal kind for the control reply.
    pub kind: ControlErrorKind,
    /// What is wrong, naming the problem.
    pub message: String,
}

impl BuildError {
    /// An `Invalid` refusal.
    pub fn invalid(message: impl Into<String>) -> Self {
        BuildError { kind: ControlErrorKind::Invalid, message: message.into() }
    }
}

/// What is wrong with a stage request.
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    /// The name is empty, too long or has characters outside `[A-Za-z0-9_-]` (shown cut to 40).
    #[error("stage name {0:?} is not valid: use 1 to {MAX_STAGE_NAME} letters, digits, '-' or '_'")]
    BadName(String),
    /// Every slot is taken.
    #[error("{MAX_STAGES} stages are running, the most at once; stop one first (frond status lists them)")]
    SlotsFull,
    /// The rig has no secondary element of that name.
    #[error("rig {rig:?} has no secondary element {layer:?} (it has: {has})")]
    NoSuchLayer {
        /// The rig's name.
        rig: String,
        /// The layer asked for.
        layer: String,
        /// The rig's secondary elements, comma-separated, or `none`.
        has: String,
    },
    /// The take could not be read.
    #[error(transparent)]
    Take(#[from] TakeError),
    /// The take is too short to loop.
    #[error("the take's global layer has {frames} frames at 30 FPS; at least 8 are needed to loop")]
    TooShortToLoop {
        /// Its frames at 30 FPS.
        frames: usize,
    },
    /// The take is longer than a live loop may be (`playback::MAX_LOOP_FRAMES` at 30 FPS).
    #[error("the take's global layer is too long to loop: {0}")]
    TooLongToLoop(frond_motion::take::TooManyFrames),
    /// No loop transitions could be found (seed 000, Eq. 5).
    #[error(transparent)]
    Loop(#[from] LoopError),
    /// The field lists no plants.
    #[error("the field has no plants")]
    EmptyField,
    /// The field is out of its limits.
    #[error(transparent)]
    Field(#[from] FieldError),
    /// A guided-motion spec is not valid (seed 000, Eq. 8).
    #[error("{0}")]
    Guided(String),
}
