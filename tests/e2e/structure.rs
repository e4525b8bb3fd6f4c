//! The code's shape, checked on the sources themselves (issue 45): what a reader can rely on
//! without reading every file.
//!
//! - No import circles between the files of one crate: a file "imports" another when it names
//!   an item through `crate::`, `super::` or `self::` that resolves into that file's module. A
//!   circle means neither file can be read, tested or moved without the other.
//! - No function over [`MAX_FN_LINES`] lines outside tests: a function a reader cannot hold at
//!   once is split by responsibility.
//! - Every library crate asks for docs on its public items (`#![warn(missing_docs)]`).
//! - `daemon/motion` is math only: no file system, no `libc`, no file format (`toml`).
//!
//! The sources are formatted by rustfmt, which these checks rely on: a function's body ends at
//! the first line that is its own indentation followed by `}`.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The longest function allowed outside tests, in lines from `fn` to its closing brace.
const MAX_FN_LINES: usize = 120;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("tests/ has a parent").to_path_buf()
}

/// Every crate of the workspace that has a `src/` directory, vendored crates excepted.
fn crate_dirs() -> Vec<PathBuf> {
    let root = workspace_root();
    let mut dirs = Vec::new();
    for group in ["daemon", "exporters", "tests", "fuzz"] {
        let group_dir = root.join(group);
        let mut candidates = vec![group_dir.clone()];
        if let Ok(entries) = fs::read_dir(&group_dir) {
            candidates.extend(entries.flatten().map(|e| e.path()));
        }
        for dir in candidates {
            if dir.join("Cargo.toml").is_file() && dir.join("src").is_dir() {
                dirs.push(dir);
            }
        }
    }
    dirs.sort();
    dirs.dedup();
    assert!(dirs.len() >= 15, "found only {} crates: {dirs:?}", dirs.len());
    dirs
}

/// The `.rs` files under `dir`, recursively, skipping `bin/` (each binary is its own crate root
/// that reaches the library by name, not by `crate::`).
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("read {}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            if path.file_name().is_some_and(|n| n != "bin") {
                rust_files(&path, out);
            }
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// A file's module path inside its crate: `src/lib.rs` is `[]`, `src/a/mod.rs` and `src/a.rs`
/// are `["a"]`, `src/a/b.rs` is `["a", "b"]`.
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).expect("file under src");
    let mut parts: Vec<String> =
        rel.with_extension("").components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    let last = parts.last().cloned().unwrap_or_default();
    if (parts.len() == 1 && (last == "lib" || last == "main")) || last == "mod" {
        parts.pop();
    }
    parts
}

/// Whether the file is a directory's module file (its `super::` is its parent's parent).
fn is_dir_module(file: &Path) -> bool {
    matches!(file.file_name().and_then(|n| n.to_str()), Some("lib.rs" | "main.rs" | "mod.rs"))
}

/// Whether the file holds only tests (`tests.rs`, `tests/...` inside `src`).
fn is_test_file(src: &Path, file: &Path) -> bool {
    file.strip_prefix(src).expect("file under src").components().any(|c| {
        let name = c.as_os_str().to_string_lossy();
        name == "tests.rs" || name == "tests"
    })
}

/// The source without comments, string and char literals, and `#[cfg(test)]` items, so that
/// neither prose nor tests count as code.
fn code_only(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < bytes.len() {
        let rest = &text[i..];
        if rest.starts_with("//") {
            let end = rest.find('\n').unwrap_or(rest.len());
            i += end;
        } else if rest.starts_with("/*") {
            let end = rest.find("*/").map_or(rest.len(), |e| e + 2);
            // Keep the line count so that line numbers stay true.
            out.extend(rest[..end].chars().filter(|&c| c == '\n'));
            i += end;
        } else if let Some(len) = raw_string_len(rest) {
            out.push_str("\"\"");
            out.extend(rest[..len].chars().filter(|&c| c == '\n'));
            i += len;
        } else if rest.starts_with('"') {
            let mut j = 1;
            while j < rest.len() {
                match rest.as_bytes()[j] {
                    b'\\' => j += 2,
                    b'"' => break,
                    _ => j += 1,
                }
            }
            let end = (j + 1).min(rest.len());
            out.push_str("\"\"");
            out.extend(rest[..end].chars().filter(|&c| c == '\n'));
            i += end;
        } else if let Some(len) = char_literal_len(rest) {
            out.push_str("' '");
            i += len;
        } else {
            let c = rest.chars().next().expect("not empty");
            out.push(c);
            i += c.len_utf8();
        }
    }
    strip_test_items(&out)
}

/// The length of a raw string literal (`r"..."`, `r#"..."#`, `br#"..."#`) at the start.
fn raw_string_len(s: &str) -> Option<usize> {
    let body = s.strip_prefix("br").or_else(|| s.strip_prefix('r'))?;
    let hashes = body.len() - body.trim_start_matches('#').len();
    let after = &body[hashes..];
    if !after.starts_with('"') {
        return None;
    }
    let closing = format!("\"{}", "#".repeat(hashes));
    let end = after[1..].find(&closing)? + 1 + closing.len();
    Some(s.len() - after.len() + end)
}

/// The length of a char literal (`'a'`, `'\n'`, `'\u{1F600}'`) at the start, and not a lifetime.
fn char_literal_len(s: &str) -> Option<usize> {
    let rest = s.strip_prefix('\'')?;
    if let Some(escaped) = rest.strip_prefix('\\') {
        // The escaped character itself may be a quote: `'\''`.
        let first = escaped.chars().next()?.len_utf8();
        let end = first + escaped[first..].find('\'')?;
        return (end <= 10).then_some(end + 3);
    }
    let c = rest.chars().next()?;
    rest[c.len_utf8()..].starts_with('\'').then_some(2 + c.len_utf8())
}

/// Removes every item that follows `#[cfg(test)]` (a `mod tests { ... }`, a test-only helper),
/// keeping its newlines.
fn strip_test_items(code: &str) -> String {
    let mut out = String::with_capacity(code.len());
    let mut rest = code;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let item = &rest[at..];
        let end = item_end(item);
        out.extend(item[..end].chars().filter(|&c| c == '\n'));
        rest = &item[end..];
    }
    out.push_str(rest);
    out
}

/// The end of the item at the start of `s`: its first `;` outside braces, or its outermost
/// closing brace.
fn item_end(s: &str) -> usize {
    let mut depth = 0usize;
    for (i, c) in s.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return i + 1;
                }
            }
            ';' if depth == 0 => return i + 1,
            _ => {}
        }
    }
    s.len()
}

/// Every path a piece of code names through `crate::`, `super::` or `self::`, `use` trees
/// (`use crate::{a::B, c::{D, E}}`) expanded.
fn named_paths(code: &str) -> Vec<Vec<String>> {
    let mut paths = Vec::new();
    let bytes = code.as_bytes();
    for start in ["crate", "super", "self"] {
        let mut from = 0;
        while let Some(at) = code[from..].find(start) {
            let begin = from + at;
            from = begin + start.len();
            let before_ok = begin == 0 || {
                let b = bytes[begin - 1];
                !(b.is_ascii_alphanumeric() || b == b'_' || b == b':' || b == b'$')
            };
            if !before_ok || !code[from..].starts_with("::") {
                continue;
            }
            use_tree(code, from + 2, vec![start.to_string()], &mut paths);
        }
    }
    paths
}

/// Reads one use tree at `i` under `prefix` into `out`; returns where it ended.
fn use_tree(code: &str, mut i: usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let bytes = code.as_bytes();
    while i < bytes.len() && bytes[i].is_ascii_whitespace() {
        i += 1;
    }
    if i < bytes.len() && bytes[i] == b'{' {
        i += 1;
        loop {
            while i < bytes.len() && (bytes[i].is_ascii_whitespace() || bytes[i] == b',') {
                i += 1;
            }
            if i >= bytes.len() || bytes[i] == b'}' {
                return i + 1;
            }
            let before = i;
            i = use_tree(code, i, prefix.clone(), out);
            if i == before {
                return i + 1;
            }
        }
    }
    let len =
        code[i..].find(|c: char| !(c.is_alphanumeric() || c == '_' || c == '*')).unwrap_or(code.len() - i);
    if len == 0 {
        out.push(prefix);
        return i;
    }
    let mut path = prefix;
    path.push(code[i..i + len].to_string());
    i += len;
    if code[i..].starts_with("::") {
        return use_tree(code, i + 2, path, out);
    }
    out.push(path);
    i
}

/// The file-level import graph of one crate: module path -> the modules it names.
fn import_graph(crate_dir: &Path) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let src = crate_dir.join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let files: Vec<(Vec<String>, PathBuf)> =
        files.into_iter().filter(|f| !is_test_file(&src, f)).map(|f| (module_path(&src, &f), f)).collect();
    let modules: BTreeSet<Vec<String>> = files.iter().map(|(m, _)| m.clone()).collect();
    let mut graph = BTreeMap::new();
    for (module, file) in &files {
        let text = fs::read_to_string(file).expect("read source");
        let code = code_only(&text);
        let mut targets = BTreeSet::new();
        for path in named_paths(&code) {
            let mut base: Vec<String> = if path[0] == "crate" {
                Vec::new()
            } else if is_dir_module(file) {
                module.clone()
            } else {
                module[..module.len().saturating_sub(1)].to_vec()
            };
            let mut rest = &path[..];
            if rest[0] == "crate" {
                rest = &rest[1..];
            }
            while let Some(first) = rest.first() {
                match first.as_str() {
                    "super" => {
                        base.pop();
                    }
                    "self" => {}
                    _ => break,
                }
                rest = &rest[1..];
            }
            base.extend(rest.iter().cloned());
            // The longest prefix that is a file's module is the file the path lands in.
            let target =
                (0..=base.len()).rev().map(|k| base[..k].to_vec()).find(|prefix| modules.contains(prefix));
            if let Some(target) = target.filter(|t| t != module) {
                targets.insert(target);
            }
        }
        graph.insert(module.clone(), targets);
    }
    graph
}

/// The strongly connected components of more than one module (Tarjan).
fn circles(graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<Vec<Vec<String>>> {
    struct Walk<'a> {
        graph: &'a BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        index: BTreeMap<&'a Vec<String>, usize>,
        low: BTreeMap<&'a Vec<String>, usize>,
        stack: Vec<&'a Vec<String>>,
        found: Vec<Vec<Vec<String>>>,
    }
    impl<'a> Walk<'a> {
        fn visit(&mut self, v: &'a Vec<String>) {
            let n = self.index.len();
            self.index.insert(v, n);
            self.low.insert(v, n);
            self.stack.push(v);
            for w in &self.graph[v] {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let low = self.low[v].min(self.low[w]);
                    self.low.insert(v, low);
                } else if self.stack.contains(&w) {
                    let low = self.low[v].min(self.index[w]);
                    self.low.insert(v, low);
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    component.push(w.clone());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.sort();
                    self.found.push(component);
                }
            }
        }
    }
    let mut walk =
        Walk { graph, index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), found: Vec::new() };
    for v in graph.keys() {
        if !walk.index.contains_key(v) {
            walk.visit(v);
        }
    }
    walk.found
}

fn module_name(module: &[String]) -> String {
    if module.is_empty() { "lib/main".to_string() } else { module.join("::") }
}

#[test]
fn no_crate_has_an_import_circle_between_its_files() {
    let root = workspace_root();
    let mut found = Vec::new();
    for dir in crate_dirs() {
        for circle in circles(&import_graph(&dir)) {
            let names: Vec<String> = circle.iter().map(|m| module_name(m)).collect();
            found.push(format!(
                "{}: {}",
                dir.strip_prefix(&root).unwrap_or(&dir).display(),
                names.join(" <-> ")
            ));
        }
    }
    assert!(
        found.is_empty(),
        "import circles between files (move what both sides need into a module both use):\n{}",
        found.join("\n")
    );
}

/// The functions of a file longer than `limit` lines, outside `#[cfg(test)]` items: (name,
/// first line, lines).
fn long_functions(code: &str, limit: usize) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = code.lines().collect();
    let mut long = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let Some(name) = fn_name(trimmed) else {
            continue;
        };
        if line.trim_end().ends_with(';') {
            continue; // a declaration in a trait or extern block
        }
        let closing = format!("{indent}}}");
        if let Some(end) = lines[i..].iter().position(|l| l.trim_end() == closing) {
            let count = end + 1;
            if count > limit {
                long.push((name, i + 1, count));
            }
        }
    }
    long
}

/// The name of the function a trimmed line starts, if it does.
fn fn_name(trimmed: &str) -> Option<String> {
    let mut rest = trimmed;
    if let Some(after) = rest.strip_prefix("pub") {
        rest = after.trim_start();
        if rest.starts_with('(') {
            rest = rest[rest.find(')')? + 1..].trim_start();
        }
    }
    for qualifier in ["const ", "async ", "unsafe ", "extern \"C\" ", "extern \"\" "] {
        if let Some(after) = rest.strip_prefix(qualifier) {
            rest = after.trim_start();
        }
    }
    let after = rest.strip_prefix("fn ")?;
    let len = after.find(|c: char| !(c.is_alphanumeric() || c == '_'))?;
    (len > 0).then(|| after[..len].to_string())
}

#[test]
fn no_function_outside_tests_passes_the_line_limit() {
    let root = workspace_root();
    let mut found = Vec::new();
    for dir in crate_dirs() {
        let src = dir.join("src");
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        if src.join("bin").is_dir() {
            rust_files(&src.join("bin"), &mut files);
        }
        for file in files.iter().filter(|f| !is_test_file(&src, f)) {
            let code = code_only(&fs::read_to_string(file).expect("read source"));
            for (name, line, count) in long_functions(&code, MAX_FN_LINES) {
                found.push(format!(
                    "{}:{line}: fn {name} is {count} lines",
                    file.strip_prefix(&root).unwrap_or(file).display()
                ));
            }
        }
    }
    assert!(
        found.is_empty(),
        "functions over {MAX_FN_LINES} lines (split them by responsibility):\n{}",
        found.join("\n")
    );
}

#[test]
fn every_library_crate_asks_for_docs() {
    let root = workspace_root();
    let missing: Vec<String> = crate_dirs()
        .into_iter()
        .filter(|dir| dir.join("src/lib.rs").is_file())
        .filter(|dir| {
            let lib = code_only(&fs::read_to_string(dir.join("src/lib.rs")).expect("read lib.rs"));
            !lib.contains("#![warn(missing_docs)]") && !lib.contains("#![deny(missing_docs)]")
        })
        .map(|dir| dir.strip_prefix(&root).unwrap_or(&dir).display().to_string())
        .collect();
    assert!(missing.is_empty(), "library crates without #![warn(missing_docs)]: {missing:?}");
}

#[test]
fn motion_is_math_without_files_or_libc() {
    let src = workspace_root().join("daemon/motion/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut found = Vec::new();
    for file in &files {
        let code = code_only(&fs::read_to_string(file).expect("read source"));
        for word in ["std::fs", "libc::", "File::", "tempfile", "std::env", "toml::"] {
            if code.contains(word) {
                found.push(format!("{}: {word}", file.display()));
            }
        }
    }
    assert!(found.is_empty(), "I/O in daemon/motion: {found:?}");
}

#[test]
fn the_checks_see_what_they_look_for() {
    // A circle of two files, a long function and a test item the checks must skip: the checks
    // above pass only if these parsers work, so they are tested on code written here.
    let code = code_only(
        "use crate::{a::B, c::{D, e::F}};\nfn f() { super::g::h(); let s = \"crate::x::y\"; }\n\
         #[cfg(test)]\nmod tests { use crate::z::Q; }\n// crate::comment::C\n",
    );
    let mut paths = named_paths(&code);
    paths.sort();
    let expect: Vec<Vec<String>> = [
        vec!["crate", "a", "B"],
        vec!["crate", "c", "D"],
        vec!["crate", "c", "e", "F"],
        vec!["super", "g", "h"],
    ]
    .iter()
    .map(|p| p.iter().map(|s| s.to_string()).collect())
    .collect();
    assert_eq!(paths, expect);

    let mut graph = BTreeMap::new();
    let a = vec!["a".to_string()];
    let b = vec!["b".to_string()];
    let c = vec!["c".to_string()];
    graph.insert(a.clone(), BTreeSet::from([b.clone()]));
    graph.insert(b.clone(), BTreeSet::from([a.clone(), c.clone()]));
    graph.insert(c.clone(), BTreeSet::new());
    assert_eq!(circles(&graph), vec![vec![a, b]]);

    let body: String = (0..130).map(|i| format!("    let x{i} = {i};\n")).collect();
    let long = format!("pub(crate) fn big() {{\n{body}}}\n#[cfg(test)]\nfn t() {{\n{body}}}\n");
    assert_eq!(long_functions(&code_only(&long), MAX_FN_LINES), vec![("big".to_string(), 1, 132)]);
}
