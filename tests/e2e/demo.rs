//! `frond demo`, the README's first command: daemon on the built-in virtual glove, a recorded
//! take left on disk, baked to a GLB, a preview of the whole take, the console's URL printed and
//! the console live until Ctrl-C (or `--stay`), and no daemon or console left behind.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use frond_e2e::bin;

/// Processes named `program` whose command line names `dir` (the test's takes directory).
fn running(program: &str, dir: &Path) -> usize {
    std::fs::read_dir("/proc")
        .unwrap()
        .filter_map(|e| std::fs::read(e.ok()?.path().join("cmdline")).ok())
        .filter(|c| {
            let c = String::from_utf8_lossy(c);
            c.split('\0').next().is_some_and(|argv0| argv0.ends_with(program))
                && c.contains(dir.to_str().unwrap())
        })
        .count()
}

/// The number of images in a GIF (its image descriptors), read by walking its blocks.
fn gif_frames(gif: &[u8]) -> usize {
    assert_eq!(&gif[..6], b"GIF89a", "not a GIF");
    let table = |flags: u8| if flags & 0x80 != 0 { 3 << ((flags & 7) + 1) } else { 0 };
    let mut at = 13 + table(gif[10]);
    let skip_sub_blocks = |mut at: usize| {
        while gif[at] != 0 {
            at += 1 + gif[at] as usize;
        }
        at + 1
    };
    let mut frames = 0;
    loop {
        match gif[at] {
            0x21 => at = skip_sub_blocks(at + 2),
            0x2c => {
                frames += 1;
                at = skip_sub_blocks(at + 10 + table(gif[at + 9]) + 1);
            }
            0x3b => return frames,
            b => panic!("GIF block 0x{b:02x} at {at}"),
        }
    }
}

/// Issue 44: the demo leaves the newcomer something to look at. The console stays up after the
/// take until Ctrl-C (here SIGINT after it said so), which ends the demo cleanly (status 0, the
/// daemon and the console gone); the preview GIF covers the whole take, not its first 1.5 s.
#[test]
fn demo_keeps_the_console_live_until_ctrl_c_and_previews_the_whole_take() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(bin("frond"))
        .args(["demo", "--seconds", "3", "--name", "live-demo"])
        .env("FROND_TAKES_DIR", dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut seen = String::new();
    let deadline = Instant::now() + Duration::from_secs(120);
    while !seen.contains("\nlive:") {
        let mut line = String::new();
        assert!(stdout.read_line(&mut line).unwrap() > 0, "frond demo ended early:\n{seen}");
        seen.push_str(&line);
        assert!(Instant::now() < deadline, "no live line:\n{seen}");
    }
    assert!(seen.contains("Ctrl-C"), "{seen}");
    // Seconds after the take, the console and the daemon are still there.
    std::thread::sleep(Duration::from_secs(3));
    assert_eq!(running("frond-console", dir.path()), 1, "the console is gone:\n{seen}");
    assert_eq!(running("frondd", dir.path()), 1, "the daemon is gone:\n{seen}");
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) }, 0);
    let status = child.wait().unwrap();
    assert!(status.success(), "Ctrl-C after the take is the demo's normal end: {status}");
    for program in ["frondd", "frond-console"] {
        assert_eq!(running(program, dir.path()), 0, "frond demo left {program} running");
    }
    // The whole take in the preview: its frames at 30 fps span the take's time.
    let take =
        frond_formats::take::scan_take(&std::fs::read(dir.path().join("live-demo.take")).unwrap()).unwrap();
    let main: Vec<f64> = take.frames.iter().filter(|f| f.element.is_global()).map(|f| f.pose.t).collect();
    let take_s = main[main.len() - 1] - main[0];
    assert!(take_s > 2.5, "a 3 s take lasted {take_s} s");
    let frames = gif_frames(&std::fs::read(dir.path().join("live-demo.gif")).unwrap());
    assert!((frames as f64 - 1.0) / 30.0 >= take_s - 1.0 / 30.0, "{frames} frames for {take_s} s");
}

#[test]
fn demo_records_a_take_bakes_a_glb_and_leaves_no_daemon() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(bin("frond"))
        .args(["demo", "--seconds", "1.5", "--name", "e2e-demo", "--stay", "0"])
        .env("FROND_TAKES_DIR", dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "demo failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let take = std::fs::read(dir.path().join("e2e-demo.take")).expect("take on disk");
    let scan = frond_formats::take::scan_take(&take).unwrap();
    assert!(scan.ended, "take not closed");
    // 1.5 s of a 1 kHz glove: every report is a frame (allow for start-up and a loaded machine).
    assert!(scan.frames.len() > 700, "{} frames", scan.frames.len());
    let seqs: Vec<u64> = scan.frames.iter().map(|f| f.seq).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "frames out of order");
    let glb = std::fs::read(dir.path().join("e2e-demo.glb")).expect("GLB baked");
    assert_eq!(&glb[..4], b"glTF", "not a GLB");
    assert!(stdout.contains("e2e-demo.glb"), "{stdout}");
    let gif = std::fs::read(dir.path().join("e2e-demo.gif")).expect("warp preview rendered");
    assert!(gif_frames(&gif) > 1, "not an animated GIF");
    // It started the console beside the daemon and said where.
    assert!(stdout.contains("console:    http://127.0.0.1:"), "{stdout}");
    // The daemon and the console it started are gone: none has our takes dir on its command line.
    for program in ["frondd", "frond-console"] {
        assert_eq!(running(program, dir.path()), 0, "frond demo left {program} running");
    }
}
