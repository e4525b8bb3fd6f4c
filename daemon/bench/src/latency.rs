//! Section 2 (in progress).
use crate::{Options, report::Section};
/// Section 2.
pub fn glove_latency(_o: &Options) -> Result<Section, String> {
    Err("todo".into())
}
