//! The virtual glove's fault schedule in the soak: when it unplugs, for how long, and how often
//! it corrupts a report. The subscribers judge their sequence gaps against the same schedule.

/// Length of each unplug window.
pub const UNPLUG_MS: u64 = 300;
/// Period of the unplugs; the first comes at [`FIRST_UNPLUG_MS`].
pub const UNPLUG_EVERY_MS: u64 = 15_000;
/// First unplug, after the glove's first report.
pub const FIRST_UNPLUG_MS: u64 = 8_000;
/// Probability that the glove corrupts a report.
pub const CORRUPT_PROB: f64 = 0.01;
