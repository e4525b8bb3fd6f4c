//! Stage timecode from LTC (issue 46): `frondd --ltc FIFO` reads a master clock's linear
//! timecode, locks to it, and a take recorded while it plays carries the stage's timecode in its
//! exports; an input that is not audio frond reads is refused at start-up.
//!
//! The LTC here is made by an encoder written in this test from the SMPTE 12M bit layout (as
//! tabulated in "Linear timecode", Wikipedia, from ITU-R BR.780-2), not from frond's code: 80
//! bits a frame, BCD fields least significant bit first (frame units at bit 0, frame tens 8-9,
//! second units 16-19, second tens 24-26, minute units 32-35, minute tens 40-42, hour units
//! 48-51, hour tens 56-57), the sync word 0011 1111 1111 1101 in bits 64-79, and biphase mark
//! code: the level flips at the start of every bit and in the middle of every 1. At 48 kHz and
//! 25 fps a bit is exactly 24 samples. A thread writes it into a FIFO in real time, 10 ms at a
//! time, each chunk just after it "played" on the test's clock (CLOCK_MONOTONIC, as frond's).

use std::io::Write;
use std::os::unix::ffi::OsStrExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use frond_e2e::{Daemon, bin, wait_for};

const RATE_HZ: usize = 48_000;
const FPS: usize = 25;
const SAMPLES_PER_BIT: usize = RATE_HZ / FPS / 80;
/// 10:00:00:00 at 25 fps, in frames since midnight.
const START_FRAME: usize = 10 * 3600 * FPS;

/// The 80 bits of the frame `count` frames after midnight at 25 fps, in transmission order.
fn frame_bits(count: usize) -> [bool; 80] {
    let (f, s) = (count % FPS, count / FPS);
    let (sec, min, hour) = (s % 60, s / 60 % 60, s / 3600 % 24);
    let mut bits = [false; 80];
    let mut bcd = |at: usize, width: usize, value: usize| {
        for i in 0..width {
            bits[at + i] = (value >> i) & 1 == 1;
        }
    };
    bcd(0, 4, f % 10);
    bcd(8, 2, f / 10);
    bcd(16, 4, sec % 10);
    bcd(24, 3, sec / 10);
    bcd(32, 4, min % 10);
    bcd(40, 3, min / 10);
    bcd(48, 4, hour % 10);
    bcd(56, 2, hour / 10);
    for (i, c) in "0011111111111101".chars().enumerate() {
        bits[64 + i] = c == '1';
    }
    // At 25 fps bit 59 makes the number of ones even (the polarity-correction bit).
    bits[59] = bits.iter().filter(|&&b| b).count() % 2 == 1;
    bits
}

/// Biphase-mark samples of frame `count`, continuing from `level` (which it updates).
fn frame_samples(count: usize, level: &mut i16, out: &mut Vec<i16>) {
    for bit in frame_bits(count) {
        *level = -*level;
        for i in 0..SAMPLES_PER_BIT {
            if bit && i == SAMPLES_PER_BIT / 2 {
                *level = -*level;
            }
            out.push(*level);
        }
    }
}

/// The label of frame `count` since midnight at 25 fps.
fn label(count: usize) -> String {
    let s = count / FPS;
    format!("{:02}:{:02}:{:02}:{:02}", s / 3600 % 24, s / 60 % 60, s % 60, count % FPS)
}

/// Frames since midnight of a label `HH:MM:SS:FF` at 25 fps.
fn frames_of(tc: &str) -> usize {
    let p: Vec<usize> = tc.split([':', ';']).map(|x| x.parse().unwrap()).collect();
    ((p[0] * 60 + p[1]) * 60 + p[2]) * FPS + p[3]
}

/// Writes LTC from 10:00:00:00 into `fifo` in real time until `stop`; returns when the first
/// sample played (sample `s` plays at that instant plus `s` / 48000 s).
fn play(fifo: &Path, stop: Arc<AtomicBool>) -> (std::thread::JoinHandle<()>, Instant) {
    let (tx, rx) = std::sync::mpsc::channel();
    let fifo = fifo.to_path_buf();
    let handle = std::thread::spawn(move || {
        let mut out = std::fs::OpenOptions::new().write(true).open(&fifo).expect("open the FIFO to write");
        let t0 = Instant::now();
        tx.send(t0).unwrap();
        let (mut level, mut frame, mut pending) = (12_000i16, START_FRAME, Vec::new());
        let chunk = RATE_HZ / 100;
        for c in 0.. {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            while pending.len() < chunk {
                frame_samples(frame, &mut level, &mut pending);
                frame += 1;
            }
            // Samples [c * chunk, (c + 1) * chunk) have played once this instant has passed.
            let due = t0 + Duration::from_millis(10 * (c + 1));
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            let bytes: Vec<u8> = pending.drain(..chunk).flat_map(i16::to_le_bytes).collect();
            if out.write_all(&bytes).is_err() {
                return;
            }
        }
    });
    let t0 = rx.recv_timeout(Duration::from_secs(10)).expect("the daemon opened the FIFO");
    (handle, t0)
}

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: `c` is a valid NUL-terminated path for the duration of the call.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
}

/// What `frond doctor` says (on stdout and stderr; it exits non-zero when it finds problems).
fn doctor(daemon: &Daemon) -> String {
    let out = daemon.frond().arg("doctor").output().unwrap();
    String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr)
}

/// The `ltc` object of `frond status --json`.
fn ltc_json(daemon: &Daemon) -> serde_json::Value {
    let out = daemon.frond_ok(&["status", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    v["ltc"].clone()
}

#[test]
fn a_take_recorded_while_ltc_plays_carries_the_stage_timecode() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("ltc.fifo");
    mkfifo(&fifo);
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--ltc", fifo.to_str().unwrap()]);
    let first = ltc_json(&daemon);
    assert_eq!(first["state"], "searching", "{first}");
    assert_eq!(first["input"], fifo.to_str().unwrap());
    let stop = Arc::new(AtomicBool::new(false));
    let (writer, t0) = play(&fifo, stop.clone());
    let mut last = serde_json::Value::Null;
    let locked = wait_for(Duration::from_secs(5), || {
        last = ltc_json(&daemon);
        last["state"] == "locked"
    });
    assert!(locked, "no lock: {last}");
    assert_eq!(last["fps"], "25", "{last}");
    let text = daemon.frond_ok(&["status"]);
    assert!(text.contains("ltc          locked at 25 fps from "), "{text}");
    assert!(!doctor(&daemon).contains("stage timecode"), "a locked input is no problem");

    // What the test's clock says was playing just before and just after the take started.
    let playing = |at: Instant| START_FRAME + (at.duration_since(t0).as_secs_f64() * FPS as f64) as usize;
    let before = Instant::now();
    daemon.frond_ok(&["record", "start", "staged"]);
    let after = Instant::now();
    std::thread::sleep(Duration::from_millis(1000));
    daemon.frond_ok(&["record", "stop"]);
    let lines = daemon.frond_ok(&["take", "export", "staged", "--fps", "25", "--timecode"]);
    let tcs: Vec<String> = lines
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["tc"].as_str().unwrap().to_string())
        .collect();
    let got = frames_of(&tcs[0]);
    let (lo, hi) = (playing(before), playing(after));
    assert!(
        got + 1 >= lo && got <= hi + 1,
        "the take starts at {} ({got}); the LTC playing then was {} to {} ({lo}..={hi})",
        tcs[0],
        label(lo),
        label(hi)
    );
    assert!(tcs[0].starts_with("10:00:0"), "{tcs:?}");
    assert!(tcs.windows(2).all(|w| frames_of(&w[1]) == frames_of(&w[0]) + 1), "{tcs:?}");
    assert!((20..=50).contains(&tcs.len()), "about a second at 25 fps: {}", tcs.len());

    // The writer goes away: the lock is lost (and says so), and doctor warns.
    stop.store(true, Ordering::Relaxed);
    writer.join().unwrap();
    let lost = wait_for(Duration::from_secs(5), || {
        last = ltc_json(&daemon);
        last["state"] == "lost"
    });
    assert!(lost, "the lock outlived its signal: {last}");
    assert!(last["losses"].as_u64().unwrap() >= 1 && last["frames"].as_u64().unwrap() > 25, "{last}");
    let said = doctor(&daemon);
    assert!(said.contains("is not locked: it lost the signal"), "{said}");
}

/// Runs `frondd` with `args` (private directories under `dir`) and expects it to refuse them.
fn refused(dir: &Path, args: &[&str]) -> String {
    let mut child = Command::new(bin("frondd"))
        .arg("--socket-dir")
        .arg(dir.join("run"))
        .arg("--takes-dir")
        .arg(dir.join("takes"))
        .args(["--source", "in-process"])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("frondd {args:?} did not refuse its input");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(2), "{args:?}: {err}");
    err
}

#[test]
fn inputs_that_are_not_ltc_audio_are_refused_naming_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.wav");
    std::fs::write(&text, "these are notes, not audio\n").unwrap();
    let err = refused(dir.path(), &["--ltc", text.to_str().unwrap()]);
    assert!(
        err.contains(&format!(
            "ltc input {}: is not a WAV file (it does not start with RIFF)",
            text.display()
        )),
        "{err}"
    );
    // A WAV header (written here from the RIFF layout) for stereo 16-bit audio.
    let mut wav = b"RIFF\x24\x00\x00\x00WAVEfmt \x10\x00\x00\x00\x01\x00\x02\x00".to_vec();
    wav.extend_from_slice(&48_000u32.to_le_bytes());
    wav.extend_from_slice(&(48_000u32 * 4).to_le_bytes());
    wav.extend_from_slice(&[4, 0, 16, 0]);
    wav.extend_from_slice(b"data\x00\x00\x00\x00");
    let stereo = dir.path().join("stereo.wav");
    std::fs::write(&stereo, wav).unwrap();
    let err = refused(dir.path(), &["--ltc", stereo.to_str().unwrap()]);
    assert!(err.contains("2 channel(s) of 16 bits; LTC is read from mono 16-bit PCM"), "{err}");
    let err = refused(dir.path(), &["--ltc", dir.path().join("absent.raw").to_str().unwrap()]);
    assert!(err.contains("absent.raw: No such file or directory"), "{err}");
    let config = dir.path().join("frondd.toml");
    std::fs::write(&config, "[ltc]\ninput = \"/dev/null\"\nfps = \"31\"\nsample_rate_hz = 1\n").unwrap();
    let err = refused(dir.path(), &["--config", config.to_str().unwrap()]);
    assert!(err.contains("ltc.sample_rate_hz: 1 is out of range 8000..=192000"), "{err}");
    assert!(err.contains("ltc.fps: \"31\" is not one of 24, 25, 29.97df, 30"), "{err}");
}
