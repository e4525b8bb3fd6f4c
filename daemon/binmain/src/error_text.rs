//! How every frond binary prints an error: one line, the error and its causes, each said once.
//!
//! Many error types print their cause in their own message and also expose it as their
//! `source()` (so that a program can inspect it); printing the whole chain, as `{:#}` does, then
//! says the same thing two or three times (`cannot read X: No such file: No such file`).
//! Here, not in the wire protocol's crate: it is about printing any error, and every binary's
//! `main` (through [`crate::exit`]) and `frond doctor` use it.

use std::error::Error;

/// The error and its causes, joined by `: `, leaving out a cause whose text the message so far
/// already contains.
pub fn error_text(e: &(dyn Error + 'static)) -> String {
    let mut out = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
        cause = c.source();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("cannot read rig {path}: {source}")]
    struct Quoting {
        path: &'static str,
        #[source]
        source: std::io::Error,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("baking failed")]
    struct Terse(#[source] Quoting);

    #[test]
    fn each_cause_is_said_once() {
        let io = || std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
        let e = Quoting { path: "/nope.toml", source: io() };
        assert_eq!(error_text(&e), "cannot read rig /nope.toml: No such file or directory");
        // A terse parent still gets its causes, once each.
        let e = Terse(Quoting { path: "/nope.toml", source: io() });
        assert_eq!(error_text(&e), "baking failed: cannot read rig /nope.toml: No such file or directory");
    }
}
