//! `frond demo`, the README's first command: daemon on the built-in virtual glove, a recorded
//! take left on disk, baked to a GLB, the console's URL printed, and no daemon or console left
//! behind.

use std::process::Command;

use frond_e2e::bin;

#[test]
fn demo_records_a_take_bakes_a_glb_and_leaves_no_daemon() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(bin("frond"))
        .args(["demo", "--seconds", "1.5", "--name", "e2e-demo"])
        .env("FROND_TAKES_DIR", dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "demo failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let take = std::fs::read(dir.path().join("e2e-demo.take")).expect("take on disk");
    let scan = frond_motion::take::scan_take(&take).unwrap();
    assert!(scan.ended, "take not closed");
    // 1.5 s of a 1 kHz glove: every report is a frame (allow for start-up and a loaded machine).
    assert!(scan.frames.len() > 700, "{} frames", scan.frames.len());
    let seqs: Vec<u64> = scan.frames.iter().map(|f| f.seq).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "frames out of order");
    let glb = std::fs::read(dir.path().join("e2e-demo.glb")).expect("GLB baked");
    assert_eq!(&glb[..4], b"glTF", "not a GLB");
    assert!(stdout.contains("e2e-demo.glb"), "{stdout}");
    let gif = std::fs::read(dir.path().join("e2e-demo.gif")).expect("warp preview rendered");
    assert_eq!(&gif[..6], b"GIF89a", "not a GIF");
    // It started the console beside the daemon and said where.
    assert!(stdout.contains("console:    http://127.0.0.1:"), "{stdout}");
    // The daemon and the console it started are gone: none has our takes dir on its command line.
    for program in ["frondd", "frond-console"] {
        let ours = std::fs::read_dir("/proc")
            .unwrap()
            .filter_map(|e| std::fs::read(e.ok()?.path().join("cmdline")).ok())
            .filter(|c| {
                let c = String::from_utf8_lossy(c);
                c.split('\0').next().is_some_and(|argv0| argv0.ends_with(program))
                    && c.contains(dir.path().to_str().unwrap())
            })
            .count();
        assert_eq!(ours, 0, "frond demo left {program} running");
    }
}
