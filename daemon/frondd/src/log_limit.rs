//! Rate-limited logging for what clients can trigger: the one mechanism of
//! [`frond_device::log_limit`], shared with the hand sources (a hand service is a peer too).

pub use frond_device::log_limit::{LINES_PER_WINDOW, LogLimit, MAX_LOGGED_CHARS, Verdict, WINDOW, cut};
