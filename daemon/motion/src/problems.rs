//! Validation problems collected with their path, so a file with several mistakes is reported in
//! one go (DEVELOPERS.md: "validated into a typed form that reports every error with its path").

use std::fmt;

/// One validation problem: where (`joints[2].height_m`) and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// Dotted path of the offending value, e.g. `joints[2].height_m`.
    pub path: String,
    /// What is wrong with it.
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.message)
    }
}

/// Every problem found while validating one document (never empty when returned as an error).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Problems(pub Vec<Problem>);

impl Problems {
    pub(crate) fn push(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.0.push(Problem { path: path.into(), message: message.into() });
    }

    /// Number of problems.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// True when nothing is wrong.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The paths of all problems, in the order found.
    pub fn paths(&self) -> Vec<&str> {
        self.0.iter().map(|p| p.path.as_str()).collect()
    }

    /// Checks that `v` is finite; reports `path: must be a finite number, found ...` otherwise.
    pub(crate) fn finite(&mut self, path: impl Into<String>, v: f32) -> bool {
        if v.is_finite() {
            true
        } else {
            self.push(path, format!("must be a finite number, found {v}"));
            false
        }
    }

    /// Checks a name from a file (a rig's, a joint's, an element's): not blank, at most
    /// `max_bytes`, and no control characters, since names are printed in status tables, take
    /// lists and logs, where an escape sequence or a line break would forge or garble output.
    /// `true` when it is fine. Also the rule for names that arrive over the control socket
    /// (marker labels), so that every name frond prints obeys one rule.
    pub fn name(&mut self, path: impl Into<String>, name: &str, max_bytes: usize) -> bool {
        let path = path.into();
        if name.trim().is_empty() {
            self.push(path, "must not be empty");
        } else if name.len() > max_bytes {
            self.push(path, format!("is {} bytes; the limit is {max_bytes}", name.len()));
        } else if let Some(c) = name.chars().find(|c| c.is_control()) {
            self.push(path, format!("contains the control character {c:?}; a name must be printable"));
        } else {
            return true;
        }
        false
    }

    /// Checks that `v` is finite and strictly positive.
    pub(crate) fn positive(&mut self, path: impl Into<String>, v: f32) -> bool {
        let path = path.into();
        if !self.finite(path.clone(), v) {
            return false;
        }
        if v > 0.0 {
            true
        } else {
            self.push(path, format!("must be greater than 0, found {v}"));
            false
        }
    }
}

impl fmt::Display for Problems {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.0.len();
        write!(f, "{n} problem{}:", if n == 1 { "" } else { "s" })?;
        for p in &self.0 {
            write!(f, "\n  {p}")?;
        }
        Ok(())
    }
}
