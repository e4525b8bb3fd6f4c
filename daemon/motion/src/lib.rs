//! Pure motion math for frond (no I/O): hand samples, rigs, calibration, jitter filters, the
//! hand-to-plant mapping of seed 000 (Eq. 2-4), and the take file codec.

pub mod sample;

pub use sample::{HandSample, JOINTS, PoseFrame};
