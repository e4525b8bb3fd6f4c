//! The kinds that start the virtual glove, parsed here beside the other backends so that one
//! table lists every kind; the glove itself is the `frond-vhid` crate (built on this one), and
//! the daemon opens it.

use super::spec::{Backend, SourceSpec, SpecError};

/// `auto`: a glove matching the device profile if one is plugged in, else the virtual glove.
pub const AUTO: Backend = Backend { syntax: "auto", parse: |kind, _| named(kind, "auto", SourceSpec::Auto) };
/// `virtual`: the virtual glove as a FUSE hidraw node (in-process where FUSE cannot mount).
pub const VIRTUAL: Backend =
    Backend { syntax: "virtual", parse: |kind, _| named(kind, "virtual", SourceSpec::Virtual) };
/// `in-process`: the virtual glove's generator inside the daemon.
pub const IN_PROCESS: Backend =
    Backend { syntax: "in-process", parse: |kind, _| named(kind, "in-process", SourceSpec::InProcess) };

fn named(kind: &str, name: &str, spec: SourceSpec) -> Option<Result<SourceSpec, SpecError>> {
    (kind == name).then_some(Ok(spec))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::SpecInput;

    #[test]
    fn only_the_exact_name_is_taken() {
        let input = SpecInput { key: "k", replay: None, replay_key: "r" };
        assert_eq!((AUTO.parse)("auto", &input), Some(Ok(SourceSpec::Auto)));
        assert_eq!((AUTO.parse)("auto:x", &input), None);
        assert_eq!((IN_PROCESS.parse)("virtual", &input), None);
    }
}
