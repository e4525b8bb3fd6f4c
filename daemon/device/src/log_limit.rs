//! Rate-limited logging for what peers can trigger: a client that sends refused requests in a
//! loop (or a 250 KB name), or a hand service that drops and takes connections as fast as it
//! can, must not flood or fill the log. One mechanism for the daemon and its hand sources. Each kind of line is logged at most
//! [`LINES_PER_WINDOW`] times per [`WINDOW`]; what is held back is counted and said in one line
//! when the next window opens. Texts are cut to [`MAX_LOGGED_CHARS`].

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Lines of one kind logged per window at most.
pub const LINES_PER_WINDOW: u32 = 10;
/// The window.
pub const WINDOW: Duration = Duration::from_secs(10);
/// Longest client text quoted in a log line, characters.
pub const MAX_LOGGED_CHARS: usize = 200;

/// One kind of log line's budget.
pub struct LogLimit {
    state: Mutex<Window>,
}

struct Window {
    started: Option<Instant>,
    logged: u32,
    held_back: u64,
}

/// What to do with one line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Verdict {
    /// Log it.
    pub log: bool,
    /// Lines held back in the window that just ended (say so first), if any.
    pub held_back_before: u64,
}

impl LogLimit {
    /// A fresh budget.
    pub const fn new() -> Self {
        LogLimit { state: Mutex::new(Window { started: None, logged: 0, held_back: 0 }) }
    }

    /// Whether a line at `now` may be logged.
    pub fn check(&self, now: Instant) -> Verdict {
        let mut w = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let mut held_back_before = 0;
        if w.started.is_none_or(|s| now.saturating_duration_since(s) >= WINDOW) {
            held_back_before = std::mem::take(&mut w.held_back);
            w.started = Some(now);
            w.logged = 0;
        }
        if w.logged < LINES_PER_WINDOW {
            w.logged += 1;
            Verdict { log: true, held_back_before }
        } else {
            w.held_back += 1;
            Verdict { log: false, held_back_before }
        }
    }
}

impl LogLimit {
    /// Runs `log` (which writes the line) if the budget allows it now, first saying in one
    /// warning how many lines of `kind` the window that just ended held back, e.g.
    /// "control refusals not logged (more than 10 in 10 s)" with `count=290`.
    pub fn log(&self, kind: &str, log: impl FnOnce()) {
        let verdict = self.check(Instant::now());
        if verdict.held_back_before > 0 {
            tracing::warn!(
                count = verdict.held_back_before,
                "{kind} not logged (more than {LINES_PER_WINDOW} in {} s)",
                WINDOW.as_secs()
            );
        }
        if verdict.log {
            log();
        }
    }
}

impl Default for LogLimit {
    fn default() -> Self {
        Self::new()
    }
}

/// `text` cut to [`MAX_LOGGED_CHARS`] characters, saying how long it was when cut.
pub fn cut(text: &str) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(MAX_LOGGED_CHARS) {
        None => std::borrow::Cow::Borrowed(text),
        Some((at, _)) => std::borrow::Cow::Owned(format!("{}... ({} bytes in all)", &text[..at], text.len())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ten_lines_a_window_then_a_count() {
        let limit = LogLimit::new();
        let t0 = Instant::now();
        let logged = (0..1000).filter(|_| limit.check(t0).log).count();
        assert_eq!(logged, 10);
        // The next window: logged again, and the 990 held back are reported once.
        let v = limit.check(t0 + WINDOW);
        assert_eq!(v, Verdict { log: true, held_back_before: 990 });
        assert_eq!(limit.check(t0 + WINDOW).held_back_before, 0);
    }

    #[test]
    fn long_texts_are_cut_and_say_their_length() {
        assert_eq!(cut("short"), "short");
        let long = "é".repeat(300);
        let c = cut(&long);
        assert!(c.starts_with(&"é".repeat(200)) && c.ends_with("... (600 bytes in all)"), "{c}");
    }
}
