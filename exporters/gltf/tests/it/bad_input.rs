//! Bad input gives a clear error naming the problem, exit status 1, and no output file (nor a
//! temporary file) left behind.

use crate::common;

use std::path::{Path, PathBuf};

use common::*;

/// Runs a bake that fails on its input (exit 1) into `dir/out.glb`; returns stderr. Checks that
/// `dir` holds nothing new.
fn fails(dir: &Path, args: &[&str]) -> String {
    fails_with(1, dir, args)
}

/// Runs a bake with an option out of range (a usage error: exit 2), as [`fails`].
fn refused(dir: &Path, args: &[&str]) -> String {
    fails_with(2, dir, args)
}

fn fails_with(code: i32, dir: &Path, args: &[&str]) -> String {
    let before: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    let out = run(args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(code), "{args:?}: {stderr}");
    assert!(stderr.starts_with("frond-gltf: error: "), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let after: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(before, after, "files left behind");
    stderr
}

/// A scratch directory with a grass take named `take_name` and an empty `keep/` directory for
/// the outputs of failing bakes (which must leave it as it was).
fn scratch(take_name: &str) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let take = grass_take(dir.path(), take_name);
    let keep = dir.path().join("keep");
    std::fs::create_dir(&keep).unwrap();
    (dir, take, keep)
}

#[test]
fn missing_take_by_name_and_by_path() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let out = format!("{d}/out.glb");
    let e = fails(dir.path(), &["bake", "--take", "nope", "--takes-dir", d, "--rig", "grass", "-o", &out]);
    assert!(e.contains("take `nope` not found") && e.contains(&format!("{d}/nope.take")), "{e}");
    let e = fails(dir.path(), &["bake", "--take", "/no/such/x.take", "--rig", "grass", "-o", &out]);
    assert!(e.contains("not found: no file /no/such/x.take"), "{e}");
    let e =
        fails(dir.path(), &["bake", "--take", "../escape", "--takes-dir", d, "--rig", "grass", "-o", &out]);
    assert!(e.contains("not found"), "{e}");
    let e =
        fails(dir.path(), &["bake", "--take", "bad name", "--takes-dir", d, "--rig", "grass", "-o", &out]);
    assert!(e.contains("take `bad name`") && e.contains("letters, digits"), "{e}");
}

#[test]
fn take_names_resolve_in_the_takes_dir_and_env() {
    let dir = tempfile::tempdir().unwrap();
    grass_take(dir.path(), "named");
    let out = dir.path().join("o.glb");
    let o = out.to_str().unwrap();
    run_ok(&[
        "bake",
        "-q",
        "--take",
        "named",
        "--takes-dir",
        dir.path().to_str().unwrap(),
        "--rig",
        "grass",
        "-o",
        o,
    ]);
    assert!(out.is_file());
    std::fs::remove_file(&out).unwrap();
    let status = std::process::Command::new(bin())
        .args(["bake", "-q", "--take", "named", "--rig", "grass", "-o", o])
        .env("FROND_TAKES_DIR", dir.path())
        .status()
        .unwrap();
    assert!(status.success() && out.is_file());
}

#[test]
fn damaged_and_empty_takes() {
    let (dir, take, keep) = scratch("good");
    let mut bytes = std::fs::read(&take).unwrap();
    let out = keep.join("out.glb");
    let o = out.to_str().unwrap();

    // A flipped byte in the middle: the reader skips the damaged record and the rest is baked,
    // with a note saying what was skipped.
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0xff;
    let bad = dir.path().join("corrupt.take");
    std::fs::write(&bad, &bytes).unwrap();
    let stderr = run_ok(&["bake", "--take", bad.to_str().unwrap(), "--rig", "grass", "-o", o]);
    assert!(stderr.contains("take `good` is damaged: 1 damaged stretch skipped"), "{stderr}");
    assert!(stderr.contains("1 frame lost; baked the readable frames"), "{stderr}");
    std::fs::remove_file(&out).unwrap();

    // Not a take at all.
    let junk = dir.path().join("junk.take");
    std::fs::write(&junk, b"hello world, not a take").unwrap();
    let e = fails(&keep, &["bake", "--take", junk.to_str().unwrap(), "--rig", "grass", "-o", o]);
    assert!(e.contains("junk.take is damaged: not a frond take: bad magic"), "{e}");
    assert_eq!(e.matches("bad magic").count(), 1, "the cause is said once (issue 18): {e}");

    // Only a header: nothing to bake.
    let empty = write_take(dir.path(), "empty", "grass", Vec::new(), &[]);
    let e = fails(&keep, &["bake", "--take", empty.to_str().unwrap(), "--rig", "grass", "-o", o]);
    assert!(e.contains("take `empty` has no frames of the main skeleton"), "{e}");

    // A torn tail (a take still being written) is baked, with a note.
    let good = std::fs::read(&take).unwrap();
    let torn = dir.path().join("torn.take");
    std::fs::write(&torn, &good[..good.len() - 5]).unwrap();
    let stderr = run_ok(&["bake", "--take", torn.to_str().unwrap(), "--rig", "grass", "-o", o]);
    assert!(stderr.contains("torn tail"), "{stderr}");
    assert!(out.is_file());
}

#[test]
fn bad_rigs() {
    let (dir, take, keep) = scratch("t");
    let t = take.to_str().unwrap();
    let o = keep.join("out.glb");
    let o = o.to_str().unwrap();

    let rig = dir.path().join("nojoints.toml");
    std::fs::write(&rig, "name = \"bare\"\njoints = []\n").unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", rig.to_str().unwrap(), "-o", o]);
    assert!(e.contains("nojoints.toml") && e.contains("joints: expected 4 joints, found 0"), "{e}");

    let rig = dir.path().join("nojoints2.toml");
    std::fs::write(&rig, "name = \"bare\"\n").unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", rig.to_str().unwrap(), "-o", o]);
    assert!(e.contains("nojoints2.toml") && e.contains("joints"), "{e}");

    let e = fails(&keep, &["bake", "--take", t, "--rig", "cactus", "-o", o]);
    assert!(e.contains("rig `cactus` not found: not an embedded rig (grass, flower, shrub)"), "{e}");

    let e = fails(&keep, &["bake", "--take", t, "--rig", "/no/such/rig.toml", "-o", o]);
    assert!(e.contains("cannot read rig /no/such/rig.toml"), "{e}");

    let rig = dir.path().join("meshfile.toml");
    std::fs::write(
        &rig,
        "name = \"m\"\njoints = [{ height_m = 0.0 }, { height_m = 0.1 }, { height_m = 0.2 }, { height_m = 0.3 }]\n[mesh]\nfile = \"missing.glb\"\n",
    )
    .unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", rig.to_str().unwrap(), "-o", o]);
    assert!(e.contains("mesh: cannot read") && e.contains("missing.glb"), "{e}");
}

#[test]
fn unwritable_outputs_leave_nothing_behind() {
    let (_dir, take, keep) = scratch("t");
    let t = take.to_str().unwrap();

    let o = keep.join("missing/out.glb");
    let e = fails(&keep, &["bake", "--take", t, "--rig", "grass", "-o", o.to_str().unwrap()]);
    assert!(e.contains("cannot write") && e.contains("does not exist"), "{e}");

    // The output is a directory.
    let sub = keep.join("sub.glb");
    std::fs::create_dir(&sub).unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", "grass", "-o", sub.to_str().unwrap()]);
    assert!(e.contains("it is a directory"), "{e}");

    // A FIFO and a link to a device stay what they are (the write once swapped them for files).
    let fifo = keep.join("fifo.glb");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let e = fails(&keep, &["bake", "--take", t, "--rig", "grass", "-o", fifo.to_str().unwrap()]);
    assert!(e.contains("it is a FIFO, not a regular file"), "{e}");
    assert!(std::os::unix::fs::FileTypeExt::is_fifo(&std::fs::symlink_metadata(&fifo).unwrap().file_type()));
    let null = keep.join("null.glb");
    std::os::unix::fs::symlink("/dev/null", &null).unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", "grass", "-o", null.to_str().unwrap()]);
    assert!(e.contains("symbolic link to a device"), "{e}");

    // The parent is a regular file.
    let file = keep.join("plain");
    std::fs::write(&file, b"x").unwrap();
    let e =
        fails(&keep, &["bake", "--take", t, "--rig", "grass", "-o", file.join("out.glb").to_str().unwrap()]);
    assert!(e.contains("cannot write"), "{e}");

    // An existing output is replaced whole, never truncated in place on failure: a failing
    // bake (bad take) leaves the old file as it was.
    let out = keep.join("old.glb");
    std::fs::write(&out, b"previous").unwrap();
    let e = fails(&keep, &["bake", "--take", "/no/such.take", "--rig", "grass", "-o", out.to_str().unwrap()]);
    assert!(e.contains("not found"), "{e}");
    assert_eq!(std::fs::read(&out).unwrap(), b"previous");
}

#[test]
fn bad_options_and_fields() {
    let (dir, take, keep) = scratch("t");
    let t = take.to_str().unwrap();
    let o = keep.join("out.glb");
    let o = o.to_str().unwrap();

    for fps in ["0", "-3", "nan", "5000"] {
        let e = refused(&keep, &["bake", "--take", t, "--rig", "grass", "-o", o, &format!("--fps={fps}")]);
        assert!(e.contains("--fps must be"), "{e}");
    }
    let good = field_json(dir.path(), 2, 0.0);
    let text = std::fs::read_to_string(&good).unwrap();
    let field = dir.path().join("f.json");
    std::fs::write(&field, text.replace("\"scale\": 1.1", "\"scale\": 0")).unwrap();
    let f = field.to_str().unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", "grass", "--field", f, "--duration", "1", "-o", o]);
    assert!(e.contains("f.json: plants[1].scale must be above 0"), "{e}");
    std::fs::write(&field, text.replace("\"version\": 1", "\"version\": 2")).unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", "grass", "--field", f, "--duration", "1", "-o", o]);
    assert!(e.contains("f.json: field.json: version 2 is not supported"), "{e}");
    let e = fails(
        &keep,
        &["bake", "--take", t, "--rig", "grass", "--field", "/no/f.json", "--duration", "1", "-o", o],
    );
    assert!(e.contains("field /no/f.json: cannot read"), "{e}");
    let g = good.to_str().unwrap();
    let e = refused(&keep, &["bake", "--take", t, "--rig", "grass", "--field", g, "--duration=-1", "-o", o]);
    assert!(e.contains("--duration: must be a number of seconds above 0"), "{e}");
    // A day at 1000 FPS is 86,400,001 keys a channel: refused before baking, never cut short
    // at 16,777,216 (as it once was, silently).
    let day = [
        "bake",
        "--take",
        t,
        "--rig",
        "grass",
        "--field",
        g,
        "--duration",
        "86400",
        "--fps",
        "1000",
        "-o",
        o,
    ];
    let e = fails(&keep, &day);
    assert!(e.contains("would be 86400001 keys, more than the limit of 1080000; pass --force"), "{e}");
    let e = fails(&keep, &[&day[..], &["--force"]].concat());
    assert!(e.contains("would be 86400001 keys, more than the limit of 16777216 (the hard limit)"), "{e}");

    // A grove: several takes, never with a field; --spacing only for a grove, and sane.
    let e =
        refused(&keep, &["bake", "--take", t, t, "--rig", "grass", "--field", g, "--duration", "1", "-o", o]);
    assert!(e.contains("--field bakes one take on every plant of the field, got 2 takes"), "{e}");
    let e = refused(&keep, &["bake", "--take", t, "--rig", "grass", "--spacing", "1", "-o", o]);
    assert!(e.contains("--spacing places the plants of a grove"), "{e}");
    for bad in ["0", "-1", "nan", "1e9"] {
        let e =
            refused(&keep, &["bake", "--take", t, t, "--rig", "grass", &format!("--spacing={bad}"), "-o", o]);
        assert!(e.contains("--spacing: must be metres above 0"), "{bad}: {e}");
    }
    let e = fails(&keep, &["bake", "--take", t, "/no/such.take", "--rig", "grass", "-o", o]);
    assert!(e.contains("/no/such.take"), "{e}");
    assert!(!keep.join("out.glb").exists());

    // --field and --duration go together (usage errors, exit 2).
    let out = run(&["bake", "--take", t, "--rig", "grass", "--field", f, "-o", o]);
    assert_eq!(out.status.code(), Some(2));
    let out = run(&["bake", "--take", t, "--rig", "grass", "--duration", "3", "-o", o]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn time_gaps_are_discontinuities_and_the_key_budget_is_checked_first() {
    let dir = tempfile::tempdir().unwrap();
    let keep = dir.path().join("keep");
    std::fs::create_dir(&keep).unwrap();
    let out = keep.join("out.glb");
    let o = out.to_str().unwrap();
    // Two frames at t = 0 and t = 1e9 (issue 14, point 7: was a 1.1 GB GLB): two keys.
    let mut two = frames(0, 0.0, 0.0, 30.0, 0.0);
    two.extend(frames(0, 1e9, 0.0, 30.0, 0.5));
    assert_eq!(two.len(), 2);
    let take = write_take(dir.path(), "jump", "grass", two, &[]);
    let stderr = run_ok(&["bake", "--take", take.to_str().unwrap(), "--rig", "grass", "-o", o]);
    assert!(stderr.contains("1 step in time longer than 1 s: each is one key"), "{stderr}");
    assert!(stderr.contains("x 2 keys"), "{stderr}");
    let size = std::fs::metadata(&out).unwrap().len();
    assert!(size < 1 << 20, "a two-key bake is {size} bytes");
    std::fs::remove_file(&out).unwrap();

    // One frame a second for 1081 s at 1000 FPS: 1,081,001 keys, past the 1,080,000 limit.
    let long = frames(0, 0.0, 1081.0, 1.0, 0.0);
    let take = write_take(dir.path(), "long", "grass", long, &[]);
    let t = take.to_str().unwrap();
    let e = fails(&keep, &["bake", "--take", t, "--rig", "grass", "--fps", "1000", "-o", o]);
    assert!(e.contains("1081001 keys, more than the limit of 1080000; pass --force"), "{e}");
}

#[test]
fn names_from_a_take_reach_the_terminal_escaped() {
    // A take's header names its rig and layers: a file's words. Printed raw, an escape sequence
    // in them would drive the operator's terminal and a line break forge a line of output.
    let dir = tempfile::tempdir().unwrap();
    let rig = "evil\u{1b}]0;owned\u{7}\nfrond-gltf: error: forged";
    let mut f = frames(0, 5.0, 1.0, 200.0, 0.0);
    f.extend(frames(1, 5.0, 1.0, 200.0, 1.0));
    let take = write_take(dir.path(), "t", rig, f, &["vine\u{1b}[2J"]);
    let out = dir.path().join("out.glb");
    let stderr =
        run_ok(&["bake", "--take", take.to_str().unwrap(), "--rig", "grass", "-o", out.to_str().unwrap()]);
    assert!(!stderr.contains(['\u{1b}', '\u{7}']), "a control character reached stderr: {stderr:?}");
    assert!(!stderr.lines().any(|l| l.starts_with("frond-gltf: error: forged")), "{stderr}");
    assert!(
        stderr.contains(r"recorded with rig `evil\u{1b}]0;owned\u{7}\nfrond-gltf: error: forged`"),
        "{stderr}"
    );
    assert!(stderr.contains(r"take layer 1 `vine\u{1b}[2J` matches no secondary element"), "{stderr}");
}

#[test]
fn the_log_level_is_checked_as_frondd_checks_it() {
    let (dir, take, keep) = scratch("t");
    let k = keep.to_str().unwrap();
    let out = format!("{k}/out.glb");
    let bake = ["bake", "--take", take.to_str().unwrap(), "--rig", "grass", "-o", &out, "--quiet"];
    // A level that does not parse is a usage error naming the option and the value, before or
    // after the subcommand, and nothing is baked.
    let e = refused(&keep, &[&bake[..], &["--log-level", "frond=loud"]].concat());
    assert!(e.starts_with("frond-gltf: error: --log-level \"frond=loud\": "), "{e}");
    let e = refused(&keep, &[&["--log-level", "loud=5=6"][..], &bake[..]].concat());
    assert!(e.starts_with("frond-gltf: error: --log-level \"loud=5=6\": "), "{e}");
    // A level and a filter are taken, in either place: the bake is made.
    for args in [
        [&bake[..], &["--log-level", "debug"]].concat(),
        [&["--log-level", "warn,frond_sdk=trace"][..], &bake[..]].concat(),
    ] {
        run_ok(&args);
        assert!(std::fs::metadata(&out).unwrap().len() > 0, "{args:?}");
        std::fs::remove_file(&out).unwrap();
    }
    drop(dir);
}
