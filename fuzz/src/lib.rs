//! Parser fuzzing on the stable toolchain (no cargo-fuzz, no nightly).
//!
//! [`fuzz`] drives one parser:
//! 1. it replays every file of `fuzz/corpus/<target>/` first (valid seeds and every input that
//!    ever failed, so a fixed bug stays fixed);
//! 2. it then runs [`case_count`] generated inputs, each derived only from the target's seed and
//!    the case index (so case `i` reproduces exactly): random bytes, random dictionary tokens, or
//!    a valid seed with 1-16 stacked structure-aware mutations (bit flips, interesting bytes and
//!    integers, truncation, deletion, duplication, splices with other seeds, dictionary tokens and
//!    interesting numbers written over the numbers of text inputs).
//!
//! Every input runs under `catch_unwind` on a worker thread with the default 2 MiB thread stack
//! (what the daemon's threads have) while a watchdog bounds its run time: a panic or an input
//! running longer than [`input_timeout`] fails the test after the input is written to
//! `fuzz/corpus/<target>/crash-<hash>` or `hang-<hash>`. Checks that a result is a typed error
//! or a well-formed value (round trips, ranges) live in the per-parser closures in `tests/`.
//!
//! Environment: `FROND_FUZZ_CASES` (generated cases per parser, default [`DEFAULT_CASES`]),
//! `FROND_FUZZ_SEED` (base seed), `FROND_FUZZ_INPUT_TIMEOUT_MS` (per input bound, default 5000),
//! `FROND_FUZZ_WRITE_SEEDS=1` (also write the built-in seeds into the corpus as `seed-NN`).

#![warn(missing_docs)]

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

mod mutate;

pub use mutate::{INTERESTING_NUMBERS, Rng, TEXT_TOKENS, Target, fnv1a, generate, mutate};

/// Generated cases per parser when `FROND_FUZZ_CASES` is not set (the CI floor).
pub const DEFAULT_CASES: u64 = 100_000;
/// Base seed when `FROND_FUZZ_SEED` is not set.
pub const DEFAULT_SEED: u64 = 0xF20D_F022_5EED_0001;

/// Generated cases per parser: `FROND_FUZZ_CASES` or [`DEFAULT_CASES`].
pub fn case_count() -> u64 {
    env_u64("FROND_FUZZ_CASES").unwrap_or(DEFAULT_CASES)
}

/// Longest time one input may run: `FROND_FUZZ_INPUT_TIMEOUT_MS` or 5 s (debug builds are slow;
/// the inputs are at most a few KiB, so any parser that takes this long is hanging).
pub fn input_timeout() -> Duration {
    Duration::from_millis(env_u64("FROND_FUZZ_INPUT_TIMEOUT_MS").unwrap_or(5000))
}

fn env_u64(name: &str) -> Option<u64> {
    let v = std::env::var(name).ok()?;
    let v = v.trim();
    let parsed = match v.strip_prefix("0x") {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => v.replace('_', "").parse().ok(),
    };
    Some(parsed.unwrap_or_else(|| panic!("{name}={v:?} is not an unsigned integer")))
}

/// The corpus directory of `name`.
pub fn corpus_dir(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("corpus").join(name)
}

/// The files of a corpus directory, sorted by name.
pub fn corpus_files(name: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = corpus_dir(name);
    let Ok(entries) = std::fs::read_dir(&dir) else { return Vec::new() };
    let mut paths: Vec<PathBuf> =
        entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file()).collect();
    paths.sort();
    paths
        .into_iter()
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("cannot read {}: {e}", p.display()));
            (p, bytes)
        })
        .collect()
}

/// Writes a failing input into the corpus; returns its path.
fn save_failure(name: &str, kind: &str, input: &[u8]) -> PathBuf {
    let dir = corpus_dir(name);
    let path = dir.join(format!("{kind}-{:016x}", fnv1a(input)));
    if let Err(e) = std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&path, input)) {
        eprintln!("frond-fuzz: cannot save the failing input to {}: {e}", path.display());
    }
    path
}

/// Figures of one fuzz run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Report {
    /// Corpus files replayed.
    pub corpus: u64,
    /// Generated inputs run.
    pub generated: u64,
    /// Slowest single input.
    pub slowest: Duration,
    /// Whole run.
    pub elapsed: Duration,
    /// How the inputs ended: the labels `check` returned, with their counts.
    pub outcomes: Vec<(&'static str, u64)>,
}

impl Report {
    /// How many inputs ended with `label`.
    pub fn count(&self, label: &str) -> u64 {
        self.outcomes.iter().filter(|(l, _)| *l == label).map(|(_, n)| n).sum()
    }
    /// Asserts that at least `per_mille` of every 1000 inputs ended with `label` (the fuzzer
    /// reaches that far). Skipped for short runs (under 10,000 generated inputs).
    pub fn assert_reaches(&self, label: &str, per_mille: u64) {
        if self.generated < 10_000 {
            return;
        }
        let total: u64 = self.outcomes.iter().map(|(_, n)| n).sum();
        assert!(
            self.count(label) * 1000 >= total * per_mille,
            "only {} of {total} inputs ended as {label:?}; the fuzzer does not reach that far: {:?}",
            self.count(label),
            self.outcomes
        );
    }
}

/// Where the worker is: which input (corpus file `i`, or generated case `i`).
const PHASE_CORPUS: u64 = 1 << 63;

/// Runs `check` on the corpus of `target` and on [`case_count`] generated inputs. Panics (after
/// saving the input into the corpus) when `check` panics or one input runs past
/// [`input_timeout`]. `check` holds the per-parser assertions; it must not panic on any input.
/// It returns a label of how the input ended (`"ok"`, `"toml"`, `"invalid"`, ...); the counts
/// are printed, so that a fuzzer that never gets past the first check shows.
pub fn fuzz<F>(target: Target, check: F) -> Report
where
    F: Fn(&[u8]) -> &'static str + Send + Sync + 'static,
{
    let start = Instant::now();
    let cases = case_count();
    let seed = env_u64("FROND_FUZZ_SEED").unwrap_or(DEFAULT_SEED) ^ fnv1a(target.name.as_bytes());
    if std::env::var_os("FROND_FUZZ_WRITE_SEEDS").is_some() {
        write_seeds(&target);
    }
    let corpus = corpus_files(target.name);
    let mut pool = target.seeds.clone();
    pool.extend(corpus.iter().map(|(_, b)| b.clone()));
    let inputs = Arc::new(Inputs { target, pool, corpus, seed });

    // The worker publishes the input it is on; the watchdog reads it when the worker stalls.
    let current = Arc::new(AtomicU64::new(u64::MAX));
    let (done_tx, done_rx) = mpsc::channel::<Done>();
    let worker = spawn_worker(Arc::clone(&inputs), cases, check, Arc::clone(&current), done_tx);
    let (slowest, labels) = watch(&inputs, worker, &done_rx, &current);
    let report = Report {
        corpus: inputs.corpus.len() as u64,
        generated: cases,
        slowest,
        elapsed: start.elapsed(),
        outcomes: labels,
    };
    let outcomes: Vec<String> = report.outcomes.iter().map(|(l, n)| format!("{l} {n}")).collect();
    eprintln!(
        "{}: {} corpus files + {} generated inputs in {:.2?} (slowest input {:.2?}); {}",
        inputs.target.name,
        report.corpus,
        report.generated,
        report.elapsed,
        report.slowest,
        outcomes.join(", ")
    );
    report
}

/// Writes the built-in seeds of `target` into its corpus as `seed-NN` (`FROND_FUZZ_WRITE_SEEDS`).
fn write_seeds(target: &Target) {
    let dir = corpus_dir(target.name);
    std::fs::create_dir_all(&dir).expect("create corpus dir");
    for (i, s) in target.seeds.iter().enumerate() {
        std::fs::write(dir.join(format!("seed-{i:02}")), s).expect("write seed");
    }
}

/// What one fuzz run draws its inputs from, shared by the worker and the watchdog: the corpus
/// (replayed first), the pool of seeds and corpus files that mutations start from, and the seed
/// every generated case derives from.
struct Inputs {
    target: Target,
    pool: Vec<Vec<u8>>,
    corpus: Vec<(PathBuf, Vec<u8>)>,
    seed: u64,
}

impl Inputs {
    /// The bytes of input `at` (corpus file or generated case), recomputed for a failure report.
    fn input_of(&self, at: u64) -> Vec<u8> {
        if at & PHASE_CORPUS != 0 {
            self.corpus[(at & !PHASE_CORPUS) as usize].1.clone()
        } else {
            generate(&self.target, &self.pool, self.seed, at)
        }
    }

    /// Input `at` named so that it can be replayed: the corpus file, or the case and its seed.
    fn describe(&self, at: u64) -> String {
        if at & PHASE_CORPUS != 0 {
            format!("corpus file {}", self.corpus[(at & !PHASE_CORPUS) as usize].0.display())
        } else {
            format!(
                "generated case {at} (FROND_FUZZ_SEED={:#x})",
                self.seed ^ fnv1a(self.target.name.as_bytes())
            )
        }
    }
}

/// What the worker reports once: the slowest input and the outcome counts, or the input that
/// panicked and its message.
type Done = Result<(Duration, Vec<(&'static str, u64)>), (u64, String)>;

/// Starts the worker thread (2 MiB stack, like the daemon's threads): it runs `check` on every
/// corpus file, then on `cases` generated inputs, each under `catch_unwind`, publishing the input
/// it is on in `current`, and sends its [`Done`] at the end or at the first panic.
fn spawn_worker<F>(
    inputs: Arc<Inputs>,
    cases: u64,
    check: F,
    current: Arc<AtomicU64>,
    done_tx: mpsc::Sender<Done>,
) -> std::thread::JoinHandle<()>
where
    F: Fn(&[u8]) -> &'static str + Send + Sync + 'static,
{
    std::thread::Builder::new()
        .name(format!("fuzz-{}", inputs.target.name))
        .stack_size(2 << 20)
        .spawn(move || {
            let mut slowest = Duration::ZERO;
            let mut labels: Vec<(&'static str, u64)> = Vec::new();
            let mut run = |at: u64, input: &[u8]| -> Result<(), (u64, String)> {
                current.store(at, Ordering::Release);
                let t = Instant::now();
                let r = catch_unwind(AssertUnwindSafe(|| check(input)));
                slowest = slowest.max(t.elapsed());
                let label = r.map_err(|p| (at, panic_text(&*p)))?;
                match labels.iter_mut().find(|(l, _)| *l == label) {
                    Some((_, n)) => *n += 1,
                    None => labels.push((label, 1)),
                }
                Ok(())
            };
            let result = (|| {
                for (i, (_, input)) in inputs.corpus.iter().enumerate() {
                    run(PHASE_CORPUS | i as u64, input)?;
                }
                for i in 0..cases {
                    let input = generate(&inputs.target, &inputs.pool, inputs.seed, i);
                    run(i, &input)?;
                }
                Ok(())
            })();
            let _ = done_tx.send(result.map(|()| (slowest, labels)));
        })
        .expect("spawn fuzz worker")
}

/// The watchdog: waits for the worker's [`Done`] while the worker must make progress on every
/// input within [`input_timeout`]. A panic or a hang saves the input into the corpus and panics
/// naming it; otherwise joins the worker and returns the slowest input and the outcome counts.
fn watch(
    inputs: &Inputs,
    worker: std::thread::JoinHandle<()>,
    done_rx: &mpsc::Receiver<Done>,
    current: &AtomicU64,
) -> (Duration, Vec<(&'static str, u64)>) {
    let name = inputs.target.name;
    let timeout = input_timeout();
    let mut last_seen = u64::MAX;
    let mut since = Instant::now();
    let done = loop {
        match done_rx.recv_timeout(Duration::from_millis(100)) {
            Ok(Ok(done)) => break done,
            Ok(Err((at, msg))) => {
                let input = inputs.input_of(at);
                let saved = save_failure(name, "crash", &input);
                let _ = worker.join();
                panic!(
                    "{}: {} panicked: {msg}\ninput ({} bytes) saved to {}",
                    name,
                    inputs.describe(at),
                    input.len(),
                    saved.display()
                );
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => panic!("{}: fuzz worker died", name),
            Err(mpsc::RecvTimeoutError::Timeout) => {
                let at = current.load(Ordering::Acquire);
                if at != last_seen {
                    last_seen = at;
                    since = Instant::now();
                } else if since.elapsed() > timeout {
                    let input = inputs.input_of(at);
                    let saved = save_failure(name, "hang", &input);
                    // The worker cannot be stopped; the panic ends the test (and the process
                    // exits when the test harness finishes).
                    panic!(
                        "{}: {} ran longer than {timeout:?} (hang)\ninput ({} bytes) saved to {}",
                        name,
                        inputs.describe(at),
                        input.len(),
                        saved.display()
                    );
                }
            }
        }
    };
    let _ = worker.join();
    done
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "(non-string panic payload)".to_string()
    }
}

/// Input bytes as text: the UTF-8 itself, or a lossy conversion (so byte-level mutations that
/// break UTF-8 still reach the parser, with U+FFFD in place of the bad bytes).
pub fn as_text(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(bytes)
}

/// Asserts that an error renders as a non-empty message (the `Display` of a typed error must
/// itself never panic and must say something).
pub fn assert_message<E: std::fmt::Display>(e: &E) {
    let msg = e.to_string();
    assert!(!msg.trim().is_empty(), "error with an empty message");
}

/// The outcome label for a parser of TOML files: `ok` once `check` has run on the parsed value,
/// `toml` for a syntax error (`is_syntax`), `invalid` for a file that parsed but did not
/// validate. Every error must render a message ([`assert_message`]).
pub fn toml_outcome<T, E: std::fmt::Display>(
    result: Result<T, E>,
    is_syntax: impl FnOnce(&E) -> bool,
    check: impl FnOnce(T),
) -> &'static str {
    match result {
        Ok(value) => {
            check(value);
            "ok"
        }
        Err(e) => {
            assert_message(&e);
            if is_syntax(&e) { "toml" } else { "invalid" }
        }
    }
}

/// Asserts that `text`, written by `what`'s own serialiser from `value`, parses back to an equal
/// value.
pub fn assert_round_trip<T: PartialEq + std::fmt::Debug, E: std::fmt::Display>(
    what: &str,
    value: &T,
    text: &str,
    parse: impl FnOnce(&str) -> Result<T, E>,
) {
    let again = parse(text).unwrap_or_else(|e| panic!("a valid {what}'s own TOML is refused: {e}\n{text}"));
    assert_eq!(&again, value, "{what} changed through to_toml_string");
}
