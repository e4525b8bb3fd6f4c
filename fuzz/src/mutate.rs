//! Input generation: a seedable generator, the fuzz target description and the structure-aware
//! mutations (bytes, integers, truncation, splices, dictionary tokens, text lines and numbers).

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
