//! Section 5 (in progress).
use crate::{Options, report::Section};
/// Section 5.
pub fn daemon_resources(_o: &Options) -> Result<Section, String> {
    Err("todo".into())
}
