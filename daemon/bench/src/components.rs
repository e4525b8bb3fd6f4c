//! Section 6 (in progress).
use crate::{
    Options,
    report::{Section, Status},
};
/// Section 6.
pub fn components(_o: &Options) -> Section {
    Section::unavailable("components", "c", Status::NotAvailable, "todo")
}
