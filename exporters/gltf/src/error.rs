//! Why a bake failed. Every message names the file or argument at fault.

use std::path::PathBuf;

use thiserror::Error;

/// Everything that can stop a bake.
#[derive(Debug, Error)]
pub enum BakeError {
    /// The take file does not exist.
    #[error("take `{arg}` not found: no file {}", path.display())]
    TakeNotFound {
        /// The `--take` argument.
        arg: String,
        /// Where it was looked for.
        path: PathBuf,
    },
    /// The take name is not a valid name (and not a path).
    #[error("take `{arg}`: {reason}")]
    TakeName {
        /// The `--take` argument.
        arg: String,
        /// What is wrong with it.
        reason: frond_protocol::paths::TakeNameError,
    },
    /// The take file could not be read, is not a regular file, or is too large.
    #[error("cannot read take {}: {}", .0.path().display(), .0.reason())]
    TakeFile(frond_formats::rig_files::FileError),
    /// The take file is damaged (bad magic, corrupt record in the middle, bad structure).
    #[error("take {origin} is damaged: {source}")]
    TakeDamaged {
        /// The take file (or `<memory>`).
        origin: String,
        /// What the take reader found.
        source: frond_formats::TakeError,
    },
    /// The bake would have more keys than the limit.
    #[error("take `{name}` at {fps} FPS would be {keys} keys, more than the limit of {limit}{hint}")]
    TooManyKeys {
        /// Take name.
        name: String,
        /// Keys the bake would have.
        keys: u64,
        /// Key rate.
        fps: f64,
        /// The limit in force.
        limit: u64,
        /// What to do about it (`; pass --force to go past it`, or that it is the hard limit).
        hint: &'static str,
    },
    /// A live field's capture would bake into more keys than the limits allow (boxed: every
    /// `Result` of the crate would otherwise carry its numbers).
    #[error(transparent)]
    LiveFieldTooLong(Box<LiveFieldTooLong>),
    /// The take holds no usable frames (of the main skeleton or of any layer).
    #[error("take `{name}` has no frames of the main skeleton or of any layer to bake")]
    TakeEmpty {
        /// Take name.
        name: String,
    },
    /// The rig could not be found, read or validated (every problem with its path).
    #[error(transparent)]
    Rig(#[from] frond_formats::rig_files::RigFileError),
    /// The rig's mesh could not be built or loaded.
    #[error("rig {origin}: mesh: {reason}")]
    RigMesh {
        /// The rig file or embedded name.
        origin: String,
        /// What went wrong.
        reason: String,
    },
    /// The field file could not be read or is invalid.
    #[error("field {origin}: {reason}")]
    Field {
        /// The field file.
        origin: String,
        /// What is wrong.
        reason: String,
    },
    /// A bake option is out of range.
    #[error("{option}: {reason}")]
    Option {
        /// The option (`--fps`).
        option: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The output could not be written (nothing is left behind).
    #[error("cannot write {}: {reason}", path.display())]
    Output {
        /// The output path.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// The document could not be serialised (a bug).
    #[error("cannot serialise the glTF document: {0}")]
    Json(String),
}

/// The numbers of [`BakeError::LiveFieldTooLong`]: what the capture needs, what fits.
#[derive(Debug, Error)]
#[error(
    "field `{field}`: {plants} plants x {keys} keys ({span_s:.1} s at {fps} FPS) are more than can be baked: \
     at most {max_keys} keys a plant ({why}); capture at most {max_s:.2} s at this rate, or at --fps \
     {max_fps:.2} or lower"
)]
pub struct LiveFieldTooLong {
    /// The field's stage name.
    pub field: String,
    /// Its plants.
    pub plants: usize,
    /// Keys a plant the capture needs.
    pub keys: u64,
    /// The captured span, seconds.
    pub span_s: f64,
    /// Key rate.
    pub fps: f64,
    /// Most keys a plant can have.
    pub max_keys: u64,
    /// Which limit that is, and what to do about it.
    pub why: String,
    /// The longest span that fits at `fps`, seconds.
    pub max_s: f64,
    /// The highest rate, in whole hundredths of a frame a second, at which this span fits
    /// `max_keys`; 0 when not even 0.01 FPS does.
    pub max_fps: f64,
}

impl LiveFieldTooLong {
    /// [`max_fps`](Self::max_fps), when some rate fits. A live performance cannot be captured
    /// again, so `frond-gltf live --field` bakes a capture past the limit at this rate rather
    /// than lose it.
    pub fn fitting_fps(&self) -> Option<f64> {
        (self.max_fps >= 0.01).then_some(self.max_fps)
    }
}
