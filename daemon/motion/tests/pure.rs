//! frond-motion is math only: no file system, no OS calls, no process or network I/O. Files and
//! their formats are frond-formats; this test keeps them from creeping back by scanning every
//! source file of the crate for the names that would do I/O.

use std::path::{Path, PathBuf};

/// Text that means I/O: the file system (`std::fs`, `File::`), raw OS calls (`libc::`), and
/// processes, sockets and streams (`std::process`, `std::net`, `std::io`).
const FORBIDDEN: [&str; 6] = ["std::fs", "File::", "libc::", "std::process", "std::net", "std::io"];

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
    // serde_json: the JSON files (field.json, the loop analysis) are frond-formats' too.
    for krate in ["libc", "tempfile", "gltf", "serde_json"] {
        assert!(
            !deps.lines().any(|l| l.trim_start().starts_with(&format!("{krate}."))
                || l.trim_start().starts_with(&format!("{krate} "))),
            "frond-motion must not depend on {krate}: file handling belongs to frond-formats"
        );
    }
}
