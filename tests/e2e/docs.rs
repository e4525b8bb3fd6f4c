//! Every command in the docs runs as written: the README's, the guide's (`docs/*.md`) and the
//! exporters' READMEs' (`exporters/*/README.md`) fenced `sh` and `bash` blocks are run, command by
//! command, against the
//! built binaries, in a private directory (socket and takes directories of its own), with a
//! daemon on the virtual glove where a block asks for one. The convention is written down in
//! `docs/README.md` ("Commands in the docs are tested"):
//!
//! - a ```` ```sh ```` block is run with `sh -c`, a ```` ```bash ```` block with `bash -c`, one
//!   command at a time (lines ending in `\` continue; `#` lines are comments); ```` ```text ````
//!   blocks are output and never run;
//! - an HTML comment on the line before the fence says how: `<!-- doc-test: skip (REASON) -->`
//!   skips the block, naming it and the reason; `daemon` starts `frondd --source in-process`
//!   for the block; `background` starts each command, checks it is still running after a
//!   moment and stops it; `repo-root` runs the block in the repository itself (for `cargo`
//!   commands, which must not write there).
//!
//! Relative links of every page must lead to files that exist, and the guide's table of contents
//! (`docs/README.md`) must link every page of `docs/`.

use std::collections::BTreeSet;
use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use frond_e2e::{Daemon, bin, repo_root};

/// How long one documented command may run before it counts as a hang.
const COMMAND_TIMEOUT: Duration = Duration::from_secs(120);

/// How long a `background` command must stay up to count as started.
const BACKGROUND_ALIVE: Duration = Duration::from_millis(1500);

/// What the marker before a block asks for.
#[derive(Debug, Default, Clone, PartialEq)]
struct Marks {
    skip: Option<String>,
    daemon: bool,
    background: bool,
    repo_root: bool,
    /// What `daemon (ARGS)` adds to the daemon's command line.
    daemon_args: Vec<String>,
}

/// One documented command: where it is and what it says.
#[derive(Debug)]
struct DocCommand {
    line: usize,
    text: String,
}

/// One fenced block to run.
#[derive(Debug)]
struct Block {
    line: usize,
    shell: &'static str,
    marks: Marks,
    commands: Vec<DocCommand>,
}

/// Parses `<!-- doc-test: ... -->`, or `None` for any other line.
fn parse_marks(line: &str) -> Result<Option<Marks>, String> {
    let Some(rest) = line.trim().strip_prefix("<!--") else { return Ok(None) };
    let Some(rest) = rest.trim().strip_prefix("doc-test:") else { return Ok(None) };
    let body = rest.trim().strip_suffix("-->").ok_or("a doc-test comment must end on its line")?.trim();
    let mut marks = Marks::default();
    if let Some(reason) = body.strip_prefix("skip") {
        let reason = reason.trim().trim_start_matches('(').trim_end_matches(')').trim();
        if reason.is_empty() {
            return Err("a skip must say why: `<!-- doc-test: skip (REASON) -->`".into());
        }
        marks.skip = Some(reason.to_string());
        return Ok(Some(marks));
    }
    for word in body.split(',').map(str::trim) {
        match word {
            "daemon" => marks.daemon = true,
            w if w.starts_with("daemon (") && w.ends_with(')') => {
                marks.daemon = true;
                marks.daemon_args =
                    w["daemon (".len()..w.len() - 1].split_whitespace().map(String::from).collect();
            }
            "background" => marks.background = true,
            "repo-root" => marks.repo_root = true,
            other => {
                return Err(format!(
                    "unknown doc-test mark `{other}` (skip, daemon, daemon (ARGS), background, repo-root)"
                ));
            }
        }
    }
    Ok(Some(marks))
}

/// The terminator word of a here-document a command starts (`<<EOF`, `<<'EOF'`, `<<-EOF`).
fn heredoc_word(cmd: &str) -> Option<String> {
    let at = cmd.find("<<")?;
    let rest = cmd[at + 2..].trim_start_matches('-').trim_start();
    let word: String = rest
        .trim_start_matches(['\'', '"'])
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    (!word.is_empty()).then_some(word)
}

/// The runnable blocks of a Markdown page, or the problems of its markers.
fn blocks(text: &str) -> Result<Vec<Block>, String> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let trimmed = lines[i].trim_start();
        let Some(tag) = trimmed.strip_prefix("```") else {
            i += 1;
            continue;
        };
        let indent = lines[i].len() - trimmed.len();
        let fence_line = i + 1;
        let mut end = i + 1;
        while end < lines.len() && !lines[end].trim_start().starts_with("```") {
            end += 1;
        }
        let shell = match tag.trim() {
            "sh" => Some("sh"),
            "bash" => Some("bash"),
            _ => None,
        };
        // The marker: the nearest non-blank line before the fence.
        let marks_line = lines[..i].iter().rev().find(|l| !l.trim().is_empty());
        let marks = match marks_line.map(|l| parse_marks(l)).transpose() {
            Ok(m) => m.flatten(),
            Err(e) => return Err(format!("line {}: {e}", fence_line - 1)),
        };
        if let Some(shell) = shell {
            let mut commands = Vec::new();
            let mut pending: Option<DocCommand> = None;
            // The terminator of a here-document being read, whose lines belong to its command.
            let mut heredoc: Option<String> = None;
            for (k, raw) in lines[i + 1..end].iter().enumerate() {
                let line = raw.get(indent..).unwrap_or(raw.trim_start());
                let number = i + 2 + k;
                if let Some(word) = &heredoc {
                    let cmd = pending.as_mut().expect("a here-document belongs to a command");
                    cmd.text.push('\n');
                    cmd.text.push_str(line);
                    if line.trim() == word {
                        heredoc = None;
                        commands.extend(pending.take());
                    }
                    continue;
                }
                let (piece, continues) = match line.trim_end().strip_suffix('\\') {
                    Some(p) => (p, true),
                    None => (line, false),
                };
                match pending.as_mut() {
                    Some(cmd) => {
                        cmd.text.push(' ');
                        cmd.text.push_str(piece.trim());
                    }
                    None if piece.trim().is_empty() || piece.trim_start().starts_with('#') => continue,
                    None => pending = Some(DocCommand { line: number, text: piece.trim().to_string() }),
                }
                if !continues {
                    heredoc = pending.as_ref().and_then(|c| heredoc_word(&c.text));
                    if heredoc.is_none() {
                        commands.extend(pending.take());
                    }
                }
            }
            if let Some(word) = heredoc {
                return Err(format!("line {fence_line}: a here-document without its `{word}` line"));
            }
            commands.extend(pending.take());
            out.push(Block { line: fence_line, shell, marks: marks.unwrap_or_default(), commands });
        } else if marks.is_some() && !tag.trim().is_empty() {
            return Err(format!(
                "line {fence_line}: a doc-test mark before a ```{} block, which is never run",
                tag.trim()
            ));
        }
        i = end + 1;
    }
    Ok(out)
}

/// A private place to run a page's commands: socket and takes directories, and a working
/// directory that sees the repository's files (rig files, scripts, exporters) through symbolic
/// links, so that what a command writes stays here.
struct Scratch {
    _dir: tempfile::TempDir,
    root: PathBuf,
    work: PathBuf,
}

impl Scratch {
    fn new() -> Scratch {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let root = dir.path().to_path_buf();
        let work = root.join("work");
        for d in ["run", "takes", "work", "data"] {
            std::fs::create_dir_all(root.join(d)).expect("scratch directories");
        }
        let repo = repo_root();
        for entry in std::fs::read_dir(&repo).expect("the repository") {
            let entry = entry.expect("a repository entry");
            let name = entry.file_name();
            // Not the build (a workspace here would build anew) nor git's own files.
            if matches!(name.to_str(), Some("target" | ".git" | "Cargo.toml" | "Cargo.lock")) {
                continue;
            }
            std::os::unix::fs::symlink(entry.path(), work.join(&name)).expect("link a repository entry");
        }
        Scratch { _dir: dir, root, work }
    }

    /// A shell running `cmd` in this scratch's environment.
    fn command(&self, shell: &str, cmd: &str, cwd: &Path) -> Command {
        let bin_dir = bin("frond").parent().expect("the binaries' directory").to_path_buf();
        let path = std::env::var_os("PATH").unwrap_or_default();
        let mut paths = vec![bin_dir];
        paths.extend(std::env::split_paths(&path));
        let mut c = Command::new(shell);
        c.arg("-c")
            .arg(cmd)
            .current_dir(cwd)
            .env("PATH", std::env::join_paths(paths).expect("a PATH"))
            .env("FROND_SOCKET_DIR", self.root.join("run"))
            .env("FROND_TAKES_DIR", self.root.join("takes"))
            .env("XDG_RUNTIME_DIR", &self.root)
            .env("XDG_DATA_HOME", self.root.join("data"))
            .env("NO_COLOR", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            // Its own process group, so that stopping it stops whatever it started.
            .process_group(0);
        c
    }
}

/// Reads what a finished or killed child wrote.
fn drain(child: &mut Child) -> String {
    let mut out = String::new();
    if let Some(mut s) = child.stdout.take() {
        let _ = s.read_to_string(&mut out);
    }
    if let Some(mut s) = child.stderr.take() {
        let _ = s.read_to_string(&mut out);
    }
    let tail: Vec<&str> = out.lines().rev().take(30).collect();
    tail.into_iter().rev().collect::<Vec<_>>().join("\n")
}

/// Stops a child's whole process group (SIGTERM, then SIGKILL after 5 s) and reaps it; returns
/// whether SIGTERM was enough.
fn stop_group(child: &mut Child) -> bool {
    let pgid = child.id() as i32;
    // The shell's children outlive it by a moment; orphaned, they would wait as zombies for
    // init to reap them (over a second on some machines). As the subreaper, this process
    // inherits them and reaps them itself, below.
    // SAFETY: prctl(2) with an integer argument, on this (the test's own) process.
    unsafe { libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1) };
    // SAFETY: kill(2) on the process group of our own child, which `process_group(0)` made.
    unsafe { libc::kill(-pgid, libc::SIGTERM) };
    // Until the whole group is gone, not only the shell: a daemon still shutting down would
    // answer the next block's checks, then remove its sockets.
    let group_gone = || {
        // SAFETY: waitpid(2) on the group's members that are (now) our children, not blocking;
        // then signal 0, which only asks whether the group exists.
        unsafe {
            while libc::waitpid(-pgid, std::ptr::null_mut(), libc::WNOHANG) > 0 {}
            libc::kill(-pgid, 0) != 0
        }
    };
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        let _ = child.try_wait();
        if group_gone() {
            let _ = child.wait();
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: as above.
    unsafe { libc::kill(-pgid, libc::SIGKILL) };
    let _ = child.wait();
    while !group_gone() {
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

/// Runs one command; `Err` says what went wrong.
fn run_command(scratch: &Scratch, block: &Block, cmd: &DocCommand) -> Result<(), String> {
    let repo = repo_root();
    let cwd = if block.marks.repo_root { repo.as_path() } else { scratch.work.as_path() };
    let mut child =
        scratch.command(block.shell, &cmd.text, cwd).spawn().map_err(|e| format!("cannot start: {e}"))?;
    if block.marks.background {
        // Output goes nowhere we wait on: a long-running command may write a lot.
        let started = Instant::now();
        while started.elapsed() < BACKGROUND_ALIVE {
            if let Ok(Some(status)) = child.try_wait() {
                return Err(format!("exited ({status}) within {BACKGROUND_ALIVE:?}:\n{}", drain(&mut child)));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        // The docs promise that SIGTERM (Ctrl-C's cousin) ends every long-running command.
        return if stop_group(&mut child) {
            Ok(())
        } else {
            Err(format!("still running 5 s after SIGTERM (killed):\n{}", drain(&mut child)))
        };
    }
    // Read the output on threads so that a chatty command never blocks on a full pipe.
    let mut stdout = child.stdout.take().expect("stdout");
    let mut stderr = child.stderr.take().expect("stderr");
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            break Some(status);
        }
        if started.elapsed() > COMMAND_TIMEOUT {
            let _ = stop_group(&mut child);
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let output = format!("{}{}", out.join().unwrap_or_default(), err.join().unwrap_or_default());
    let tail: Vec<&str> = output.lines().rev().take(30).collect();
    let tail = tail.into_iter().rev().collect::<Vec<_>>().join("\n");
    match status {
        Some(s) if s.success() => Ok(()),
        Some(s) => Err(format!("{s}:\n{tail}")),
        None => Err(format!("still running after {COMMAND_TIMEOUT:?} (stopped):\n{tail}")),
    }
}

/// Runs every block of `page` (a path relative to the repository); returns the failures and
/// prints what it skipped.
fn run_page(page: &str) -> Vec<String> {
    let path = repo_root().join(page);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{page}: {e}"));
    let blocks = match blocks(&text) {
        Ok(b) => b,
        Err(e) => return vec![format!("{page}:{e}")],
    };
    let scratch = Scratch::new();
    let mut failures = Vec::new();
    for block in &blocks {
        if let Some(reason) = &block.marks.skip {
            let first = block.commands.first().map_or("", |c| c.text.as_str());
            eprintln!("doc-test: SKIP {page}:{} `{first}`: {reason}", block.line);
            continue;
        }
        let args: Vec<&str> = ["--source", "in-process"]
            .into_iter()
            .chain(block.marks.daemon_args.iter().map(String::as_str))
            .collect();
        let _daemon = block.marks.daemon.then(|| Daemon::start(&scratch.root, &args));
        for cmd in &block.commands {
            let started = Instant::now();
            let result = run_command(&scratch, block, cmd);
            eprintln!(
                "doc-test: {} {page}:{} `{}` ({:.1} s)",
                if result.is_ok() { "ok  " } else { "FAIL" },
                cmd.line,
                cmd.text,
                started.elapsed().as_secs_f64()
            );
            if let Err(e) = result {
                failures.push(format!("{page}:{}: `{}` failed: {e}", cmd.line, cmd.text));
                // Later commands of the block build on this one.
                break;
            }
        }
    }
    failures
}

/// The exporters' READMEs, relative to the repository.
fn exporter_pages() -> Vec<String> {
    let mut pages: Vec<String> = std::fs::read_dir(repo_root().join("exporters"))
        .expect("exporters/")
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .map(|n| format!("exporters/{n}/README.md"))
        .filter(|p| repo_root().join(p).is_file())
        .collect();
    pages.sort();
    pages
}

/// The guide's pages, relative to the repository.
fn guide_pages() -> Vec<String> {
    let mut pages: Vec<String> = std::fs::read_dir(repo_root().join("docs"))
        .expect("docs/")
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    pages.sort();
    pages
}

fn assert_all_ran(failures: Vec<String>) {
    assert!(failures.is_empty(), "documented commands that fail as written:\n{}", failures.join("\n\n"));
}

/// One test per page, so that pages run side by side and each has the whole time limit.
macro_rules! pages {
    ($($test:ident => $page:literal,)*) => {
        $(
            #[test]
            fn $test() {
                assert_all_ran(run_page($page));
            }
        )*
        /// Every page with a test above.
        const PAGES: &[&str] = &[$($page),*];
    };
}

pages! {
    readme => "README.md",
    guide_toc => "docs/README.md",
    guide_commands => "docs/commands.md",
    guide_exporters => "docs/exporters.md",
    guide_file_formats => "docs/file-formats.md",
    guide_hand_sources => "docs/hand-sources.md",
    guide_live_modes => "docs/live-modes.md",
    guide_mapping => "docs/mapping.md",
    guide_mocap_stage => "docs/mocap-stage.md",
    guide_methods => "docs/methods.md",
    guide_performance => "docs/performance.md",
    guide_protocol => "docs/protocol.md",
    guide_realtime => "docs/realtime.md",
    guide_security_and_limits => "docs/security-and-limits.md",
    guide_simulation_and_graphs => "docs/simulation-and-graphs.md",
    guide_stage => "docs/stage.md",
    guide_testing => "docs/testing.md",
    guide_zenoh => "docs/zenoh.md",
    exporter_console => "exporters/console/README.md",
    exporter_gltf => "exporters/gltf/README.md",
    exporter_osc => "exporters/osc/README.md",
    exporter_sdk => "exporters/sdk/README.md",
    exporter_warp => "exporters/warp/README.md",
    exporter_zenoh => "exporters/zenoh/README.md",
}

#[test]
fn every_guide_page_and_exporter_readme_has_its_test() {
    let missing: Vec<String> =
        guide_pages().into_iter().chain(exporter_pages()).filter(|p| !PAGES.contains(&p.as_str())).collect();
    assert!(missing.is_empty(), "add these pages to `pages!` in tests/e2e/docs.rs: {missing:?}");
}

/// The `frond` subcommands that write a take (or a take's graph file) named by their arguments.
const TAKE_TOOLS: &[&str] = &["resample", "filter", "splice", "loop", "retime", "guided", "align", "walk"];

/// The takes (and graph files, `NAME.graph.json`) a documented command creates in the takes
/// directory: `frond take simulate NAME`, `take import FILE NAME`, `record start|layer NAME`,
/// `take graph NAME` and the toolkit's `-o OUT` (default `NAME-<command>`); `record start NAME
/// --stage` makes `NAME-<source>` for each source. A command that only
/// prints (`--jsonl`, `loop --explain`) creates none.
fn takes_created(cmd: &str) -> Vec<String> {
    let mut out = Vec::new();
    // Each line of the command, without its comment, split at `;`, `&&` and pipes.
    for line in cmd.lines() {
        let line = line.split(" #").next().unwrap_or(line);
        for part in line.split([';', '|', '&']) {
            let words: Vec<&str> = part.split_whitespace().map(|w| w.trim_matches(['\'', '"'])).collect();
            let Some(start) = words.iter().position(|w| *w == "frond") else { continue };
            let words = &words[start + 1..];
            let positional = |at: usize| words.get(at).filter(|w| !w.starts_with('-')).map(|w| w.to_string());
            let option = |names: &[&str]| {
                words
                    .iter()
                    .position(|w| names.contains(w))
                    .and_then(|i| words.get(i + 1))
                    .map(|w| w.to_string())
            };
            let prints = words.contains(&"--jsonl");
            match (words.first().copied(), words.get(1).copied()) {
                (Some("take"), Some("simulate")) => out.extend(positional(2)),
                (Some("take"), Some("import")) if !prints => out.extend(positional(3)),
                // With --stage, one take per source of the stage: NAME-<source>.
                (Some("record"), Some("start")) if words.contains(&"--stage") => {
                    out.extend(positional(2).map(|n| format!("{n}-<source>")))
                }
                (Some("record"), Some("start" | "layer")) => out.extend(positional(2)),
                (Some("take"), Some("graph")) => out
                    .extend(option(&["-o", "--output"]).or(positional(2).map(|n| format!("{n}.graph.json")))),
                (Some("take"), Some(tool)) if TAKE_TOOLS.contains(&tool) => {
                    if prints || (tool == "loop" && words.contains(&"--explain")) {
                        continue;
                    }
                    out.extend(option(&["-o", "--output"]).or(positional(2).map(|n| format!("{n}-{tool}"))));
                }
                _ => {}
            }
        }
    }
    out
}

/// Each page names its own takes, so that a reader can follow the pages in any order in one
/// takes directory: a take two pages create would stop the second with "exists; use --force".
/// A static check (the pages' tests each run in a directory of their own): no take name is
/// created by two pages, skipped blocks included.
#[test]
fn no_two_pages_create_the_same_take() {
    let mut creators: std::collections::BTreeMap<String, BTreeSet<String>> = Default::default();
    for page in PAGES {
        let text = std::fs::read_to_string(repo_root().join(page)).unwrap_or_else(|e| panic!("{page}: {e}"));
        let blocks = blocks(&text).unwrap_or_else(|e| panic!("{page}:{e}"));
        for cmd in blocks.iter().flat_map(|b| &b.commands) {
            for take in takes_created(&cmd.text) {
                creators.entry(take).or_default().insert(format!("{page}:{}", cmd.line));
            }
        }
    }
    let shared: Vec<String> = creators
        .iter()
        .filter(|(_, at)| at.iter().map(|a| a.split(':').next()).collect::<BTreeSet<_>>().len() > 1)
        .map(|(take, at)| format!("`{take}`: {}", at.iter().cloned().collect::<Vec<_>>().join(", ")))
        .collect();
    assert!(
        shared.is_empty(),
        "takes created by more than one page (give each page its own names):\n{}",
        shared.join("\n")
    );
}

#[test]
fn takes_created_reads_the_commands_that_write_takes() {
    let cases: &[(&str, &[&str])] = &[
        ("frond take simulate gust --rig shrub --wind speed=3 --duration 4", &["gust"]),
        ("frond take import poses.jsonl mapped", &["mapped"]),
        ("frond take import poses.jsonl mapped --jsonl", &[]),
        ("frond record start base", &["base"]),
        ("frond record layer leafy --layer leaf --over base", &["leafy"]),
        ("frond record start take1 --stage stage1 --connect tcp/10.0.0.2:7447", &["take1-<source>"]),
        ("frond take graph meadow --control top", &["meadow.graph.json"]),
        ("frond take walk a b --plants 6 --duration 60 -o mixed  # plant p walks take p mod 2", &["mixed"]),
        ("frond take align sway fast --window 2", &["sway-align"]),
        ("frond take loop sway --explain", &[]),
        ("frond take export sway --bvh -o sway.bvh", &[]),
        ("frond-gltf bake --take sway -o sway.glb && frond take resample sway --fps 60 -o s60", &["s60"]),
    ];
    for (cmd, want) in cases {
        assert_eq!(takes_created(cmd), *want, "{cmd}");
    }
}

/// Relative link targets of a Markdown text (`](target)`), without their `#anchor`.
fn relative_links(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let Some(end) = rest.find(')') else { break };
            let target = &rest[..end];
            rest = &rest[end..];
            if target.contains("://") || target.starts_with('#') || target.starts_with("mailto:") {
                continue;
            }
            let file = target.split('#').next().unwrap_or(target);
            if !file.is_empty() {
                out.push((n + 1, file.to_string()));
            }
        }
    }
    out
}

#[test]
fn docs_links_lead_somewhere_and_the_guide_lists_every_page() {
    let repo = repo_root();
    let mut pages = vec!["README.md".to_string(), "ARCHITECTURE.md".to_string()];
    pages.extend(guide_pages());
    pages.extend(exporter_pages());
    let mut broken = Vec::new();
    for page in &pages {
        let text = std::fs::read_to_string(repo.join(page)).expect("a page");
        let dir = repo.join(page).parent().expect("a directory").to_path_buf();
        for (line, target) in relative_links(&text) {
            if !dir.join(&target).exists() {
                broken.push(format!("{page}:{line}: {target}"));
            }
        }
    }
    assert!(broken.is_empty(), "links to nothing:\n{}", broken.join("\n"));
    let toc = std::fs::read_to_string(repo.join("docs/README.md")).expect("docs/README.md");
    let linked: BTreeSet<String> = relative_links(&toc).into_iter().map(|(_, t)| t).collect();
    let unlisted: Vec<String> = guide_pages()
        .into_iter()
        .filter(|p| p != "docs/README.md")
        .filter(|p| !linked.contains(p.trim_start_matches("docs/")))
        .collect();
    assert!(unlisted.is_empty(), "pages docs/README.md does not list: {unlisted:?}");
}

#[test]
fn the_marker_parser_reads_what_the_guide_documents() {
    let page = "text\n<!-- doc-test: skip (needs a glove) -->\n```sh\nfrond tap\n```\n\n\
                <!-- doc-test: daemon, background -->\n\n```sh\nfrond-console \\\n  --listen x   # a\n# c\n\nfrond status\n```\n\
                ```text\nfrond not run\n```\n```bash\necho {a,b}\n```\n";
    let b = blocks(page).expect("valid marks");
    assert_eq!(b.len(), 3);
    assert_eq!(b[0].marks.skip.as_deref(), Some("needs a glove"));
    assert_eq!((b[0].line, b[0].commands[0].line, b[0].commands[0].text.as_str()), (3, 4, "frond tap"));
    assert!(b[1].marks.daemon && b[1].marks.background && !b[1].marks.repo_root);
    let texts: Vec<&str> = b[1].commands.iter().map(|c| c.text.as_str()).collect();
    assert_eq!(texts, ["frond-console --listen x   # a", "frond status"]);
    assert_eq!(b[1].commands[1].line, 14);
    assert_eq!((b[2].shell, b[2].marks.clone()), ("bash", Marks::default()));
    let h = blocks("```sh\ncat > a.toml <<'EOF'\nx = 1\n# kept\nEOF\nfrondd --config a.toml\n```\n")
        .expect("a heredoc");
    let texts: Vec<&str> = h[0].commands.iter().map(|c| c.text.as_str()).collect();
    assert_eq!(texts, ["cat > a.toml <<'EOF'\nx = 1\n# kept\nEOF", "frondd --config a.toml"]);
    assert!(blocks("```sh\ncat <<EOF\nx\n```\n").is_err(), "an unterminated heredoc");
    assert!(blocks("<!-- doc-test: skip -->\n```sh\nx\n```\n").is_err(), "a skip without a reason");
    assert!(blocks("<!-- doc-test: deamon -->\n```sh\nx\n```\n").is_err(), "a misspelt mark");
    let d =
        blocks("<!-- doc-test: daemon (--triggers 127.0.0.1:1512) -->\n```sh\nfrond status\n```\n").unwrap();
    assert!(d[0].marks.daemon && !d[0].marks.background);
    assert_eq!(d[0].marks.daemon_args, ["--triggers", "127.0.0.1:1512"]);
}
