//! Issue 14, points 4, 5, 7 and 8: takes under disk faults, damage, absurd time spans and
//! non-finite values, against the real `frondd`, `frond` and `frond-gltf`. The limits asserted
//! are the ones docs/security-and-limits.md documents.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::hostile::rss_kib;
use frond_e2e::{Daemon, bin, wait_for};
use frond_formats::take::{TakeRecord, encode_file_start, encode_record};
use frond_motion::{HandSample, PoseFrame, TakeFrame, TakeHeader};
use frond_protocol::ElementId;

/// A tmpfs of `size` mounted at `dir`, unmounted when dropped (even when the test fails).
struct Tmpfs(PathBuf);

impl Tmpfs {
    /// `None` (the test is skipped, saying why) when this machine refuses the mount.
    fn mount(dir: &Path, size: &str) -> Option<Tmpfs> {
        std::fs::create_dir_all(dir).unwrap();
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .output();
        match out {
            Ok(o) if o.status.success() => Some(Tmpfs(dir.to_owned())),
            Ok(o) => {
                eprintln!(
                    "SKIPPED: cannot mount a tmpfs at {} (needs root): {}",
                    dir.display(),
                    String::from_utf8_lossy(&o.stderr).trim()
                );
                None
            }
            Err(e) => {
                eprintln!("SKIPPED: cannot run mount: {e}");
                None
            }
        }
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// The records of a take file, walked by their length prefixes as the format doc describes
/// (`len u32 | crc u32 | kind u8 | payload`, after the 8-byte magic): `(offset, kind, seq)` with
/// `seq` for frames. Independent of the reader under test.
fn records(bytes: &[u8]) -> Vec<(usize, u8, Option<u64>)> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= bytes.len() {
        let len = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        if at + 8 + len > bytes.len() {
            break;
        }
        let kind = bytes[at + 8];
        let seq = (kind == 2).then(|| u64::from_le_bytes(bytes[at + 9..at + 17].try_into().unwrap()));
        out.push((at, kind, seq));
        at += 8 + len;
    }
    out
}

fn header(name: &str) -> TakeHeader {
    TakeHeader {
        created_unix_s: 1_700_000_000,
        joint_names: ["root", "lower", "middle", "tip"].map(String::from).to_vec(),
        ..TakeHeader::offline(name, "grass", 30)
    }
}

/// A take written with the project's encoder: one frame per `(t, root pitch)`.
fn write_take(dir: &Path, name: &str, frames: &[(f64, f32)]) -> PathBuf {
    let mut b = Vec::new();
    encode_file_start(&mut b);
    encode_record(&TakeRecord::Header(header(name)), &mut b);
    for (k, &(t, v)) in frames.iter().enumerate() {
        let f = TakeFrame {
            seq: k as u64,
            device_time_us: 0,
            host_ns: k as u64,
            flags: 0,
            element: ElementId::GLOBAL,
            pose: PoseFrame { t, joints_deg: [[v, 0.0, 0.0]; 4] },
            hand: HandSample { t: if t.is_finite() { t } else { 0.0 }, ..Default::default() },
        };
        encode_record(&TakeRecord::Frame(f), &mut b);
    }
    encode_record(&TakeRecord::End { frames: frames.len() as u64 }, &mut b);
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{name}.take"));
    std::fs::write(&path, b).unwrap();
    path
}

/// `frond-gltf bake` of the take at `take` on the grass rig into `glb`.
fn bake(take: &Path, glb: &Path) -> std::process::Output {
    Command::new(bin("frond-gltf"))
        .args(["bake", "--take"])
        .arg(take)
        .args(["--rig", "grass", "-o"])
        .arg(glb)
        .output()
        .unwrap()
}

#[test]
fn a_full_disk_mid_recording_keeps_every_record_closes_when_space_returns_and_reports_once() {
    let dir = tempfile::tempdir().unwrap();
    let takes = dir.path().join("takes");
    let Some(_tmpfs) = Tmpfs::mount(&takes, "256k") else { return };
    // Half the disk is taken by a file freed later: the take fills the rest in about a second.
    let filler = takes.join("filler");
    std::fs::write(&filler, vec![1u8; 128 * 1024]).unwrap();
    let log = dir.path().join("frondd.log");
    let daemon = Daemon::start_with_stderr(
        dir.path(),
        &["--source", "in-process"],
        Stdio::from(std::fs::File::create(&log).unwrap()),
    );
    daemon.frond_ok(&["record", "start", "full"]);
    let path = takes.join("full.take");
    assert!(
        wait_for(Duration::from_secs(20), || daemon.status().recorder_error.is_some()),
        "the disk never filled"
    );
    // While the disk is full: status says so, naming the take and what is kept.
    let fault = daemon.status().recorder_error.unwrap();
    assert!(fault.contains(&path.display().to_string()) && fault.contains("No space left"), "{fault}");
    assert!(fault.contains("keeps its first") && fault.contains("not recorded"), "{fault}");
    let shown = daemon.frond_ok(&["status"]);
    assert!(shown.contains("recorder     ERROR: writing take"), "{shown}");
    // It stays full for a while: the recorder retries and the log must not fill up.
    std::thread::sleep(Duration::from_secs(3));
    let rec = daemon.status().recording.expect("still a take");
    let on_disk = std::fs::read(&path).unwrap();
    let kept = records(&on_disk).iter().filter(|r| r.1 == 2).count() as u64;
    assert_eq!(rec.frames, kept, "status and the disk disagree");

    // Space returns: the take is closed, with every frame it had.
    std::fs::remove_file(&filler).unwrap();
    assert!(
        wait_for(Duration::from_secs(10), || {
            daemon.status().recorder_error.is_some_and(|e| e.contains("closed with an End record"))
        }),
        "the take was not closed when space returned: {:?}",
        daemon.status().recorder_error
    );
    let bytes = std::fs::read(&path).unwrap();
    let scan = frond_formats::scan_take(&bytes).unwrap();
    assert!(scan.ended && scan.torn_bytes == 0 && scan.skipped.is_empty(), "{scan:?}");
    assert!(scan.frames.len() as u64 >= kept && !scan.frames.is_empty());
    // No frame that was on the disk during the fault is lost: they start the closed take.
    let during: Vec<u64> = records(&on_disk).iter().filter_map(|r| r.2).collect();
    let after: Vec<u64> = scan.frames.iter().map(|f| f.seq).collect();
    assert_eq!(&after[..during.len()], &during[..], "a frame written before the fault is missing");

    // `record stop` reports the fault (once) and the daemon is no longer recording.
    let out = daemon.frond().args(["record", "stop"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(&path.display().to_string()) && err.contains("not recorded"), "{err}");
    let status = daemon.status();
    assert!(status.recording.is_none() && status.recorder_error.is_none(), "{status:?}");
    daemon.frond_ok(&["record", "start", "after"]);
    daemon.frond_ok(&["record", "stop"]);
    let take_list = daemon.frond_ok(&["take", "list", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&take_list).unwrap();
    let full = v.as_array().unwrap().iter().find(|r| r["name"] == "full").unwrap();
    assert_eq!(full["state"], "complete", "{take_list}");

    // One warning for the fault (it lasted seconds, retried every second), not one per retry.
    let log = std::fs::read_to_string(&log).unwrap();
    let warnings =
        log.lines().filter(|l| l.contains("WARN frond_recorder") && l.contains("full.take")).count();
    assert_eq!(warnings, 1, "{warnings} warnings about the take:\n{log}");
    assert!(log.contains("the disk takes writes again: the take was closed"), "{log}");
}

#[test]
fn a_flipped_bit_in_a_recorded_take_costs_only_the_record_it_hits() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    daemon.frond_ok(&["record", "start", "flip"]);
    std::thread::sleep(Duration::from_millis(1500));
    daemon.frond_ok(&["record", "stop"]);
    let path = daemon.takes_dir.join("flip.take");
    let good = std::fs::read(&path).unwrap();
    let recs = records(&good);
    let frames: Vec<u64> = recs.iter().filter_map(|r| r.2).collect();
    assert!(frames.len() > 100, "{} frames", frames.len());
    // A bit in the middle of the middle frame record's payload.
    let (hit_at, _, hit_seq) = recs.iter().filter(|r| r.1 == 2).nth(frames.len() / 2).copied().unwrap();
    let mut bad = good.clone();
    bad[hit_at + 60] ^= 0x08;
    std::fs::write(&path, &bad).unwrap();
    let want: Vec<u64> = frames.iter().copied().filter(|&s| Some(s) != hit_seq).collect();

    // Every frame before and after it is read: export, list, the baker, repair.
    let out = daemon.frond().args(["take", "export", "flip", "--include-held"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let warn = String::from_utf8_lossy(&out.stderr);
    assert!(
        warn.contains(&format!("127 bytes at offset {hit_at}")) && warn.contains("1 frame lost"),
        "{warn}"
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), want.len());

    let list = daemon.frond_ok(&["take", "list", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&list).unwrap();
    assert_eq!(v[0]["state"], "damaged", "{list}");
    assert_eq!(v[0]["frames"], want.len() as u64, "{list}");

    let glb = dir.path().join("flip.glb");
    let out = bake(&path, &glb);
    let note = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{note}");
    assert!(note.contains("is damaged: 1 damaged stretch skipped"), "{note}");

    let msg = daemon.frond_ok(&["take", "repair", "flip"]);
    assert!(
        msg.contains(&format!("dropped 127 bytes at offset {hit_at} (checksum mismatch); 1 frame lost")),
        "{msg}"
    );
    let repaired = std::fs::read(&path).unwrap();
    let got: Vec<u64> = records(&repaired).iter().filter_map(|r| r.2).collect();
    assert_eq!(got, want);
    let scan = frond_formats::scan_take(&repaired).unwrap();
    assert!(scan.ended && scan.skipped.is_empty());
    // A second repair right away: nothing to do, not "may still be recording".
    let again = daemon.frond_ok(&["take", "repair", "flip"]);
    assert!(again.contains("nothing to repair"), "{again}");
}

#[test]
fn a_take_spanning_1e9_seconds_costs_frames_not_gigabytes() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    // Two frames at t = 0 and t = 1e9 (issue 14, point 7).
    write_take(&daemon.takes_dir, "two", &[(0.0, 1.0), (1e9, 2.0)]);
    let out = daemon.frond().args(["take", "export", "two", "--fps", "30"]).output().unwrap();
    assert!(out.status.success());
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 2);
    assert!(String::from_utf8_lossy(&out.stderr).contains("discontinuity"));

    let glb = dir.path().join("two.glb");
    let path = daemon.takes_dir.join("two.take");
    let out = bake(&path, &glb);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let size = std::fs::metadata(&glb).unwrap().len();
    assert!(size < 1 << 20, "the GLB of two frames is {size} bytes");

    // Playing: the two-frame take is too short to loop (refused, said so); ten frames on each
    // side of the gap loop, and the daemon stays small.
    let pid = daemon.proc.child.id();
    let rss_before = rss_kib(pid);
    let out = daemon.frond().args(["play", "two"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("at least 8 are needed"));
    let frames: Vec<(f64, f32)> = (0..10)
        .map(|k| (k as f64 / 30.0, k as f32))
        .chain((0..10).map(|k| (1e9 + k as f64 / 30.0, 10.0 + k as f32)))
        .collect();
    write_take(&daemon.takes_dir, "gap", &frames);
    daemon.frond_ok(&["play", "gap"]);
    let rss_after = rss_kib(pid);
    assert!(rss_after < rss_before + 50 * 1024, "RSS grew from {rss_before} KiB to {rss_after} KiB");
    daemon.frond_ok(&["play", "--stop"]);
}

#[test]
fn non_finite_values_in_a_take_are_refused_by_frame() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let mut frames: Vec<(f64, f32)> = (0..40).map(|k| (k as f64 / 30.0, k as f32)).collect();
    frames[5].1 = f32::NAN;
    write_take(&daemon.takes_dir, "nan", &frames);
    frames[5].1 = 5.0;
    frames[7].0 = f64::INFINITY;
    write_take(&daemon.takes_dir, "inf", &frames);
    for (take, frame) in [("nan", "frame 5 (seq 5"), ("inf", "frame 7 (seq 7")] {
        for cmd in [&["play", take][..], &["take", "export", take]] {
            let out = daemon.frond().args(cmd).output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{cmd:?}: {err}");
            assert!(out.stdout.is_empty() || cmd[0] == "play", "{cmd:?}");
            assert!(err.contains(frame) && err.contains("non-finite"), "{cmd:?}: {err}");
        }
    }
    assert!(daemon.status().stages.is_empty(), "a take with NaN is playing");
}

/// Issue 14, points 5, 7 and 9, live: the daemon loops what a damaged take still holds and
/// says so (status, log, `frond play`); a take longer than a live loop may be is refused before
/// it is resampled; a FIFO named like a take is refused at once instead of blocking a control
/// thread.
#[test]
fn live_stages_play_what_a_take_holds_refuse_what_is_too_long_and_never_block_on_a_fifo() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);

    // Damaged: one flipped bit in the 20th of 60 frames.
    let frames: Vec<(f64, f32)> = (0..60).map(|k| (k as f64 / 30.0, (k % 10) as f32)).collect();
    let path = write_take(&daemon.takes_dir, "hurt", &frames);
    let mut bytes = std::fs::read(&path).unwrap();
    let (at, _, _) = records(&bytes).into_iter().filter(|r| r.1 == 2).nth(20).unwrap();
    bytes[at + 60] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let out = daemon.frond().args(["play", "hurt"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("warning: looping take hurt") && err.contains("1 damaged stretch skipped"), "{err}");
    assert!(err.contains("looping the readable frames"), "{err}");
    let stage = daemon.status().stages.into_iter().find(|s| s.name == "playback").expect("playing");
    assert!(stage.state.contains("(damaged: 1 damaged stretch skipped"), "{}", stage.state);
    daemon.frond_ok(&["play", "--stop"]);

    // Too long: 40 001 frames 0.9 s apart (each step interpolated) span 36 000 s, which is
    // 36 000 * 30 + 1 = 1 080 001 frames at 30 FPS, one past the limit of 1 080 000.
    let long: Vec<(f64, f32)> = (0..40_001).map(|k| (k as f64 * 0.9, (k % 7) as f32)).collect();
    write_take(&daemon.takes_dir, "long", &long);
    let out = daemon.frond().args(["play", "long"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "too long to loop: resampling at 30 FPS gives 1080001 frames, more than the limit of 1080000"
        ),
        "{err}"
    );

    // A FIFO where a take should be: refused, naming what it is, without waiting for a writer.
    let fifo = daemon.takes_dir.join("pipe.take");
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only creates a node there.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let t0 = std::time::Instant::now();
    let out = daemon.frond().args(["play", "pipe"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("it is a FIFO, not a regular file"), "{err}");
    assert!(t0.elapsed() < Duration::from_secs(5), "took {:?}", t0.elapsed());
    assert!(daemon.status().stages.is_empty());
}
