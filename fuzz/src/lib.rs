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

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

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

/// A small, fast, seedable generator (SplitMix64).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        debug_assert!(n > 0);
        ((self.next_u64() as u128 * n as u128) >> 64) as usize
    }
    /// True with probability `num / den`.
    pub fn chance(&mut self, num: u32, den: u32) -> bool {
        (self.below(den as usize) as u32) < num
    }
    /// A length in `0..=max`, biased towards short ones.
    pub fn len(&mut self, max: usize) -> usize {
        match self.below(4) {
            0 => self.below(max.min(16) + 1),
            1 => self.below(max.min(128) + 1),
            _ => self.below(max + 1),
        }
    }
    /// One element of `items` (not empty).
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// 64-bit FNV-1a, for file names and per-target seeds.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01B3);
    }
    h
}

/// What a parser is fed with.
#[derive(Debug, Clone)]
pub struct Target {
    /// Corpus directory name under `fuzz/corpus/`.
    pub name: &'static str,
    /// Valid inputs to mutate (the corpus files are added to them).
    pub seeds: Vec<Vec<u8>>,
    /// Tokens of the format (keywords, punctuation, magic numbers) for insertion.
    pub dict: Vec<Vec<u8>>,
    /// Longest generated input.
    pub max_len: usize,
    /// Text format: also overwrite numbers in the text with interesting numbers.
    pub text: bool,
    /// Structure repair applied to 3 of 4 generated inputs after mutation (fix a length prefix,
    /// a checksum, ...) so that mutations reach past the outer integrity checks.
    pub fixup: Option<fn(&mut Vec<u8>, &mut Rng)>,
}

impl Target {
    /// A target with no seeds yet, a 4 KiB input limit and an empty dictionary.
    pub fn new(name: &'static str) -> Self {
        Target { name, seeds: Vec::new(), dict: Vec::new(), max_len: 4096, text: false, fixup: None }
    }
    /// Adds valid inputs.
    pub fn seeds<I: IntoIterator<Item = S>, S: AsRef<[u8]>>(mut self, seeds: I) -> Self {
        self.seeds.extend(seeds.into_iter().map(|s| s.as_ref().to_vec()));
        self
    }
    /// Adds dictionary tokens.
    pub fn dict<I: IntoIterator<Item = S>, S: AsRef<[u8]>>(mut self, tokens: I) -> Self {
        self.dict.extend(tokens.into_iter().map(|s| s.as_ref().to_vec()));
        self
    }
    /// Sets the longest generated input.
    pub fn max_len(mut self, max_len: usize) -> Self {
        self.max_len = max_len;
        self
    }
    /// Sets the structure repair (see [`Target::fixup`]).
    pub fn fixup(mut self, fixup: fn(&mut Vec<u8>, &mut Rng)) -> Self {
        self.fixup = Some(fixup);
        self
    }
    /// Marks the format as text (adds the generic text dictionary too).
    pub fn text(mut self) -> Self {
        self.text = true;
        self.dict.extend(TEXT_TOKENS.iter().map(|t| t.as_bytes().to_vec()));
        self
    }
}

/// Numbers that break parsers: limits, non-finite spellings, huge exponents, signs.
pub const INTERESTING_NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "0.0",
    "-0.0",
    "2",
    "3",
    "4",
    "63",
    "64",
    "65",
    "255",
    "256",
    "4095",
    "4096",
    "4097",
    "65535",
    "65536",
    "2147483647",
    "-2147483648",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "1e308",
    "1e309",
    "-1e309",
    "1e-320",
    "1e-45",
    "3.5e38",
    "3.4028236e38",
    "nan",
    "inf",
    "-inf",
    "+inf",
    "NaN",
    "Infinity",
    "0x7fffffff",
    "0xffffffff",
    "1_000",
    "00",
    "1.",
    ".5",
    "1e",
    "-",
    "+",
    "99999999999999999999999999999999999999",
    "0.1",
    "180",
    "180.01",
    "-180",
    "360",
];

/// Generic text tokens: brackets, quotes, escapes, separators, odd characters.
pub const TEXT_TOKENS: &[&str] = &[
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    "\"",
    "'",
    "\"\"\"",
    "'''",
    "=",
    ",",
    ":",
    ".",
    "\n",
    "\r\n",
    "\t",
    " ",
    "#",
    "\\",
    "\\u0000",
    "\\uD800",
    "\\x",
    "\0",
    "\u{feff}",
    "\u{1F331}",
    "é",
    "true",
    "false",
    "null",
    "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
    "{a={a={a={a={a={a={a={a=",
    "a.b.c.d.e.f.g.h = 1",
    "1979-05-27T07:32:00Z",
];

const INTERESTING_U8: [u8; 12] = [0, 1, 2, 0x7f, 0x80, 0x81, 0xfe, 0xff, 0x0a, 0x22, 0x5b, 0x3d];
const INTERESTING_U32: [u32; 14] = [
    0,
    1,
    4,
    5,
    63,
    64,
    65,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    1 << 20,
    (1 << 20) + 1,
    0x7fc0_0000, // f32 NaN
    0x7f80_0000, // f32 +inf
];
const INTERESTING_U64: [u64; 6] =
    [0, u64::MAX, i64::MAX as u64, 0x7ff8_0000_0000_0000, 0x7ff0_0000_0000_0000, 0xfff0_0000_0000_0000];

/// The input of generated case `index` of `target` with seed pool `pool` and base `seed`.
/// Pure: the same arguments always give the same bytes.
pub fn generate(target: &Target, pool: &[Vec<u8>], seed: u64, index: u64) -> Vec<u8> {
    let mut rng = Rng::new(seed ^ index.wrapping_mul(0xD6E8_FEB8_6659_FD93));
    rng.next_u64();
    let max = target.max_len;
    let strategy = rng.below(20);
    let mut out = if strategy == 0 || pool.is_empty() {
        let n = rng.len(max);
        (0..n).map(|_| rng.next_u64() as u8).collect()
    } else if strategy == 1 && !target.dict.is_empty() {
        let mut v = Vec::new();
        for _ in 0..1 + rng.below(24) {
            let tok: &Vec<u8> = rng.pick(target.dict.as_slice());
            v.extend_from_slice(tok);
        }
        v
    } else {
        let mut v = rng.pick(pool).clone();
        let rounds = if rng.chance(1, 8) { 1 + rng.below(16) } else { 1 + rng.below(4) };
        for _ in 0..rounds {
            mutate(&mut v, target, pool, &mut rng);
        }
        v
    };
    out.truncate(max);
    if let Some(fixup) = target.fixup
        && rng.chance(3, 4)
    {
        fixup(&mut out, &mut rng);
    }
    out
}

/// Applies one random mutation to `v`.
pub fn mutate(v: &mut Vec<u8>, target: &Target, pool: &[Vec<u8>], rng: &mut Rng) {
    let n = v.len();
    let pos = |rng: &mut Rng, n: usize| if n == 0 { 0 } else { rng.below(n + 1) };
    if target.text && rng.chance(1, 2) {
        text_mutation(v, rng);
        return;
    }
    match rng.below(if target.text { 13 } else { 11 }) {
        // Bit flip.
        0 if n > 0 => {
            let i = rng.below(n);
            v[i] ^= 1 << rng.below(8);
        }
        // Interesting byte.
        1 if n > 0 => {
            let i = rng.below(n);
            v[i] = *rng.pick(INTERESTING_U8.as_slice());
        }
        // Random byte.
        2 if n > 0 => {
            let i = rng.below(n);
            v[i] = rng.next_u64() as u8;
        }
        // Interesting little-endian integer.
        3 if n >= 4 => {
            let i = rng.below(n - 3);
            let x = rng.pick(INTERESTING_U32.as_slice()).to_le_bytes();
            v[i..i + 4].copy_from_slice(&x);
        }
        4 if n >= 8 => {
            let i = rng.below(n - 7);
            let x = rng.pick(INTERESTING_U64.as_slice()).to_le_bytes();
            v[i..i + 8].copy_from_slice(&x);
        }
        // Truncation.
        5 => v.truncate(pos(rng, n)),
        // Delete a range.
        6 if n > 0 => {
            let a = rng.below(n);
            let b = (a + 1 + rng.len(n - a - 1)).min(n);
            v.drain(a..b);
        }
        // Duplicate a range of itself somewhere.
        7 if n > 0 => {
            let a = rng.below(n);
            let b = (a + 1 + rng.len(n - a - 1)).min(n);
            let chunk = v[a..b].to_vec();
            let at = pos(rng, n);
            v.splice(at..at, chunk);
        }
        // Splice: our prefix, another seed's suffix.
        8 if !pool.is_empty() => {
            let other = rng.pick(pool);
            let cut = pos(rng, n);
            let from = pos(rng, other.len()).min(other.len());
            v.truncate(cut);
            v.extend_from_slice(&other[from..]);
        }
        // Dictionary token inserted or written over.
        9 | 10 if !target.dict.is_empty() => {
            let tok = rng.pick(target.dict.as_slice()).clone();
            let at = pos(rng, n);
            if rng.chance(1, 2) || at + tok.len() > n {
                v.splice(at..at, tok);
            } else {
                v[at..at + tok.len()].copy_from_slice(&tok);
            }
        }
        // Text: an interesting number written over a number of the text.
        11 | 12 => {
            let spans = number_spans(v);
            let num = rng.pick(INTERESTING_NUMBERS).as_bytes().to_vec();
            if spans.is_empty() {
                let at = pos(rng, n);
                v.splice(at..at, num);
            } else {
                let (a, b) = *rng.pick(spans.as_slice());
                v.splice(a..b, num);
            }
        }
        // Fallback (the chosen mutation did not apply): insert a random byte.
        _ => {
            let at = pos(rng, n);
            v.insert(at, rng.next_u64() as u8);
        }
    }
}

/// Line-aware text mutations that keep most of a document's syntax intact: an interesting
/// number over a number, a line deleted, duplicated or moved.
fn text_mutation(v: &mut Vec<u8>, rng: &mut Rng) {
    let lines: Vec<(usize, usize)> = {
        let mut out = Vec::new();
        let mut a = 0;
        for (i, &b) in v.iter().enumerate() {
            if b == b'\n' {
                out.push((a, i + 1));
                a = i + 1;
            }
        }
        if a < v.len() {
            out.push((a, v.len()));
        }
        out
    };
    match rng.below(4) {
        0 | 1 => {
            let spans = number_spans(v);
            if !spans.is_empty() {
                let (a, b) = *rng.pick(spans.as_slice());
                v.splice(a..b, rng.pick(INTERESTING_NUMBERS).bytes());
            }
        }
        _ if lines.len() < 2 => {}
        2 => {
            let (a, b) = *rng.pick(lines.as_slice());
            v.drain(a..b);
        }
        _ => {
            let (a, b) = *rng.pick(lines.as_slice());
            let line = v[a..b].to_vec();
            let (at, _) = *rng.pick(lines.as_slice());
            if rng.chance(1, 2) {
                v.drain(a..b);
                let at = if at > a { at - (b - a) } else { at };
                v.splice(at..at, line);
            } else {
                v.splice(at..at, line);
            }
        }
    }
}

/// Byte ranges of the numbers (digits with sign, dot, exponent) in a text.
fn number_spans(v: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < v.len() {
        if v[i].is_ascii_digit() {
            let mut a = i;
            if a > 0 && (v[a - 1] == b'-' || v[a - 1] == b'+') {
                a -= 1;
            }
            let mut b = i;
            while b < v.len() && (v[b].is_ascii_digit() || matches!(v[b], b'.' | b'e' | b'E' | b'_')) {
                b += 1;
            }
            spans.push((a, b));
            i = b;
        } else {
            i += 1;
        }
    }
    spans
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
        let dir = corpus_dir(target.name);
        std::fs::create_dir_all(&dir).expect("create corpus dir");
        for (i, s) in target.seeds.iter().enumerate() {
            std::fs::write(dir.join(format!("seed-{i:02}")), s).expect("write seed");
        }
    }
    let corpus = corpus_files(target.name);
    let mut pool = target.seeds.clone();
    pool.extend(corpus.iter().map(|(_, b)| b.clone()));
    let target = Arc::new(target);
    let pool = Arc::new(pool);
    let corpus_bytes: Arc<Vec<Vec<u8>>> = Arc::new(corpus.iter().map(|(_, b)| b.clone()).collect());

    // The worker publishes the input it is on; the watchdog reads it when the worker stalls.
    let current = Arc::new(AtomicU64::new(u64::MAX));
    type Done = Result<(Duration, Vec<(&'static str, u64)>), (u64, String)>;
    let (done_tx, done_rx) = mpsc::channel::<Done>();
    let worker = {
        let (target, pool, corpus_bytes, current) =
            (Arc::clone(&target), Arc::clone(&pool), Arc::clone(&corpus_bytes), Arc::clone(&current));
        std::thread::Builder::new()
            .name(format!("fuzz-{}", target.name))
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
                    for (i, input) in corpus_bytes.iter().enumerate() {
                        run(PHASE_CORPUS | i as u64, input)?;
                    }
                    for i in 0..cases {
                        let input = generate(&target, &pool, seed, i);
                        run(i, &input)?;
                    }
                    Ok(())
                })();
                let _ = done_tx.send(result.map(|()| (slowest, labels)));
            })
            .expect("spawn fuzz worker")
    };

    let input_of = |at: u64| -> Vec<u8> {
        if at & PHASE_CORPUS != 0 {
            corpus_bytes[(at & !PHASE_CORPUS) as usize].clone()
        } else {
            generate(&target, &pool, seed, at)
        }
    };
    let describe = |at: u64| -> String {
        if at & PHASE_CORPUS != 0 {
            format!("corpus file {}", corpus[(at & !PHASE_CORPUS) as usize].0.display())
        } else {
            format!("generated case {at} (FROND_FUZZ_SEED={:#x})", seed ^ fnv1a(target.name.as_bytes()))
        }
    };

    // Watchdog: the worker must make progress on every input within the timeout.
    let timeout = input_timeout();
    let mut last_seen = u64::MAX;
    let mut since = Instant::now();
    let (slowest, labels) = loop {
        match done_rx.recv_timeout(Duration::from_millis(100)) {
            Ok(Ok(done)) => break done,
            Ok(Err((at, msg))) => {
                let input = input_of(at);
                let saved = save_failure(target.name, "crash", &input);
                let _ = worker.join();
                panic!(
                    "{}: {} panicked: {msg}\ninput ({} bytes) saved to {}",
                    target.name,
                    describe(at),
                    input.len(),
                    saved.display()
                );
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => panic!("{}: fuzz worker died", target.name),
            Err(mpsc::RecvTimeoutError::Timeout) => {
                let at = current.load(Ordering::Acquire);
                if at != last_seen {
                    last_seen = at;
                    since = Instant::now();
                } else if since.elapsed() > timeout {
                    let input = input_of(at);
                    let saved = save_failure(target.name, "hang", &input);
                    // The worker cannot be stopped; the panic ends the test (and the process
                    // exits when the test harness finishes).
                    panic!(
                        "{}: {} ran longer than {timeout:?} (hang)\ninput ({} bytes) saved to {}",
                        target.name,
                        describe(at),
                        input.len(),
                        saved.display()
                    );
                }
            }
        }
    };
    let _ = worker.join();
    let report = Report {
        corpus: corpus.len() as u64,
        generated: cases,
        slowest,
        elapsed: start.elapsed(),
        outcomes: labels,
    };
    let outcomes: Vec<String> = report.outcomes.iter().map(|(l, n)| format!("{l} {n}")).collect();
    eprintln!(
        "{}: {} corpus files + {} generated inputs in {:.2?} (slowest input {:.2?}); {}",
        target.name,
        report.corpus,
        report.generated,
        report.elapsed,
        report.slowest,
        outcomes.join(", ")
    );
    report
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generation_is_reproducible_and_varied() {
        let t = Target::new("unit").seeds(["name = \"x\"\nlen = 64\n"]).text();
        let pool = t.seeds.clone();
        let a: Vec<_> = (0..200).map(|i| generate(&t, &pool, 7, i)).collect();
        let b: Vec<_> = (0..200).map(|i| generate(&t, &pool, 7, i)).collect();
        assert_eq!(a, b);
        let distinct: std::collections::HashSet<_> = a.iter().collect();
        assert!(distinct.len() > 150, "only {} distinct inputs of 200", distinct.len());
        assert!(a.iter().all(|v| v.len() <= t.max_len));
    }

    #[test]
    fn number_spans_find_signed_decimals() {
        assert_eq!(number_spans(b"a = -1.5e3, b=7"), vec![(4, 10), (14, 15)]);
    }
}
