//! frond-motion is math only: no file system, no OS calls, no process or network I/O, no file
//! formats. Files and their formats are frond-formats; this test keeps them from creeping back by
//! scanning every source file of the crate for the names that would do I/O or read a format, and
//! its manifest for the crates that would.

use std::path::{Path, PathBuf};

/// Text that means I/O: the file system (`std::fs`, `File::`), raw OS calls (`libc::`), and
/// processes, sockets and streams (`std::process`, `std::net`, `std::io`).
const FORBIDDEN: [&str; 6] = ["std::fs", "File::", "libc::", "std::process", "std::net", "std::io"];

/// Crates of file formats, refused as a path (`toml::from_str`) that is not the tail of a longer
/// name (`frond_formats::rig_toml::RigText` in a doc comment is fine): rig, calibration and
/// `[sim]` text is `frond_formats::rig_toml`.
const FORBIDDEN_CRATES: [&str; 1] = ["toml"];

/// Whether `line` names `krate` as the first segment of a path (`toml::`).
fn uses_crate(line: &str, krate: &str) -> bool {
    let path = format!("{krate}::");
    line.match_indices(&path)
        .any(|(at, _)| !line[..at].chars().next_back().is_some_and(|c| c.is_alphanumeric() || c == '_'))
}

/// Every `.rs` file under `dir`, recursively.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|x| x == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn motion_sources_do_no_io() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    assert!(files.len() > 20, "found only {} source files under {}", files.len(), src.display());
    let mut found = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        for (n, line) in text.lines().enumerate() {
            for word in FORBIDDEN.iter().filter(|w| line.contains(*w)) {
                found.push(format!("{}:{}: {word}", file.display(), n + 1));
            }
            for krate in FORBIDDEN_CRATES.iter().filter(|k| uses_crate(line, k)) {
                found.push(format!("{}:{}: {krate}::", file.display(), n + 1));
            }
        }
    }
    assert!(
        found.is_empty(),
        "frond-motion must not do I/O (move it to frond-formats):\n{}",
        found.join("\n")
    );
}

#[test]
fn motion_depends_on_no_io_crates() {
    let manifest = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml"))
        .expect("motion's Cargo.toml");
    let deps = manifest.split("[dependencies]").nth(1).expect("a [dependencies] table");
    let deps = deps.split("\n[").next().unwrap_or(deps);
    // serde_json: the JSON files (field.json, the loop analysis) are frond-formats' too; toml:
    // the rig, calibration and `[sim]` text.
    for krate in ["libc", "tempfile", "gltf", "serde_json", "toml"] {
        assert!(
            !deps.lines().any(|l| l.trim_start().starts_with(&format!("{krate}."))
                || l.trim_start().starts_with(&format!("{krate} "))),
            "frond-motion must not depend on {krate}: file handling belongs to frond-formats"
        );
    }
}

/// The path check finds a crate's paths and only those.
#[test]
fn uses_crate_finds_paths_not_name_tails() {
    assert!(uses_crate("let r: Raw = toml::from_str(text)?;", "toml"));
    assert!(uses_crate("toml::to_string(&raw)", "toml"));
    assert!(uses_crate("x(&toml::Value::Integer(1))", "toml"));
    assert!(!uses_crate("/// `frond_formats::rig_toml::RigText`", "toml"));
    assert!(!uses_crate("let toml = 1; // a toml file", "toml"));
}
