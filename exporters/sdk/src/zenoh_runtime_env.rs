//! `ZENOH_RUNTIME`, checked before Zenoh reads it.
//!
//! Zenoh sizes its thread pools from this environment variable (RON, e.g.
//! `ZENOH_RUNTIME='(rx: (worker_threads: 1), app: (handover: rx))'`) the first time a session
//! needs them, and panics on a value it cannot parse, even an empty one, or on a pool of zero
//! threads. [`check`] parses the value as Zenoh does (the same RON extensions, the same field
//! names, unknown fields refused) and bounds the sizes, so a bad value is an error naming the
//! variable and the problem instead of a panic deep in Zenoh.

use std::env::VarError;

use serde::Deserialize;

/// The variable.
pub const VAR: &str = "ZENOH_RUNTIME";
/// Most worker threads one pool may be given.
pub const MAX_WORKER_THREADS: usize = 256;
/// Most blocking threads one pool may be given.
pub const MAX_BLOCKING_THREADS: usize = 4096;
/// Longest value read.
const MAX_LEN: usize = 4096;

/// A pool's name, as Zenoh spells it.
#[derive(Debug, Deserialize)]
#[allow(non_camel_case_types, dead_code)]
enum Pool {
    app,
    acc,
    tx,
    rx,
    net,
}

/// One pool's parameters (Zenoh's `RuntimeParamHelper`: any field may be left out).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default, rename = "RuntimeParamHelper")]
struct Params {
    worker_threads: usize,
    max_blocking_threads: usize,
    #[allow(dead_code)]
    handover: Option<Pool>,
}

impl Default for Params {
    fn default() -> Self {
        Params { worker_threads: 1, max_blocking_threads: 1, handover: None }
    }
}

/// The whole value (Zenoh's `AbstractRuntimeParam`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "AbstractRuntimeParam")]
struct Pools {
    #[serde(default)]
    app: Params,
    #[serde(default)]
    acc: Params,
    #[serde(default)]
    tx: Params,
    #[serde(default)]
    rx: Params,
    #[serde(default)]
    net: Params,
}

/// Why Zenoh would refuse a `ZENOH_RUNTIME` value.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum RuntimeValueError {
    /// Longer than this module reads.
    #[error("{len} bytes; at most {MAX_LEN}")]
    TooLong {
        /// The value's length in bytes.
        len: usize,
    },
    /// Not RON in the shape Zenoh reads (unknown pool or field, wrong type, bad syntax).
    #[error("not Zenoh's runtime syntax ({0}); for example `(rx: (worker_threads: 1))`")]
    Syntax(Box<ron::error::SpannedError>),
    /// A pool's `worker_threads` outside 1 to [`MAX_WORKER_THREADS`] (Zenoh panics on 0).
    #[error("{pool}.worker_threads is {threads}; 1 to {MAX_WORKER_THREADS}")]
    WorkerThreads {
        /// The pool, as Zenoh spells it.
        pool: &'static str,
        /// The value given.
        threads: usize,
    },
    /// A pool's `max_blocking_threads` outside 1 to [`MAX_BLOCKING_THREADS`].
    #[error("{pool}.max_blocking_threads is {threads}; 1 to {MAX_BLOCKING_THREADS}")]
    BlockingThreads {
        /// The pool, as Zenoh spells it.
        pool: &'static str,
        /// The value given.
        threads: usize,
    },
}

/// This process's `ZENOH_RUNTIME` holds a value Zenoh would refuse: the value and why.
#[derive(Debug, PartialEq, thiserror::Error)]
#[error("{VAR}={value:?}: {why}; unset it for Zenoh's defaults")]
pub struct RuntimeEnvError {
    /// The variable's value.
    pub value: String,
    /// What is wrong with it (printed in this message, so not also a `source`).
    pub why: RuntimeValueError,
}

/// Checks `value` as a `ZENOH_RUNTIME` setting; the problem when Zenoh would refuse it.
pub fn check_value(value: &str) -> Result<(), RuntimeValueError> {
    if value.len() > MAX_LEN {
        return Err(RuntimeValueError::TooLong { len: value.len() });
    }
    let pools: Pools = ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str(value)
        .map_err(|e| RuntimeValueError::Syntax(Box::new(e)))?;
    for (pool, p) in
        [("app", &pools.app), ("acc", &pools.acc), ("tx", &pools.tx), ("rx", &pools.rx), ("net", &pools.net)]
    {
        if !(1..=MAX_WORKER_THREADS).contains(&p.worker_threads) {
            return Err(RuntimeValueError::WorkerThreads { pool, threads: p.worker_threads });
        }
        if !(1..=MAX_BLOCKING_THREADS).contains(&p.max_blocking_threads) {
            return Err(RuntimeValueError::BlockingThreads { pool, threads: p.max_blocking_threads });
        }
    }
    Ok(())
}

/// Checks this process's `ZENOH_RUNTIME` (unset, or not Unicode, is Zenoh's defaults).
pub fn check() -> Result<(), RuntimeEnvError> {
    match std::env::var(VAR) {
        Ok(value) => check_value(&value).map_err(|why| RuntimeEnvError { value, why }),
        Err(VarError::NotPresent | VarError::NotUnicode(_)) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_zenoh_documents_pass() {
        // The example in zenoh-runtime's documentation, and the default.
        let example = "(\n  rx: (handover: app),\n  acc: (handover: app),\n  app: (worker_threads: 2),\n  tx: (max_blocking_threads: 1)\n)";
        for ok in ["()", example, "(rx: (worker_threads: 1))", "AbstractRuntimeParam(net: (handover: tx))"] {
            assert_eq!(check_value(ok), Ok(()), "{ok}");
        }
    }

    #[test]
    fn values_zenoh_would_panic_on_are_refused_with_the_reason() {
        for (bad, says) in [
            ("", "syntax"),
            ("garbage", "syntax"),
            ("(rx: (workers: 1))", "syntax"),
            ("(gpu: ())", "syntax"),
            ("(rx: (handover: disk))", "syntax"),
            ("(rx: (worker_threads: 0))", "rx.worker_threads is 0"),
            ("(tx: (max_blocking_threads: 0))", "tx.max_blocking_threads is 0"),
            ("(app: (worker_threads: 100000))", "1 to 256"),
            ("(rx: (worker_threads: -1))", "syntax"),
        ] {
            let err = check_value(bad).unwrap_err().to_string();
            assert!(err.contains(says), "{bad:?}: {err}");
        }
        assert!(check_value(&" ".repeat(MAX_LEN + 1)).unwrap_err().to_string().contains("at most"));
    }
}
