//! Stage timecode from LTC (issue 46): `frondd --ltc FIFO|alsa:DEVICE` reads a master clock's linear
//! timecode, locks to it, and a take recorded while it plays carries the stage's timecode in its
//! exports; an input that is not audio frond reads is refused at start-up.
//!
//! The LTC here is made by an encoder written in this test from the SMPTE 12M bit layout (as
//! tabulated in "Linear timecode", Wikipedia, from ITU-R BR.780-2), not from frond's code: 80
//! bits a frame, BCD fields least significant bit first (frame units at bit 0, frame tens 8-9,
//! second units 16-19, second tens 24-26, minute units 32-35, minute tens 40-42, hour units
//! 48-51, hour tens 56-57), the sync word 0011 1111 1111 1101 in bits 64-79, and biphase mark
//! code: the level flips at the start of every bit and in the middle of every 1. At 48 kHz and
//! 25 fps a bit is exactly 24 samples; at 29.97 drop-frame 20.02 (the drop-frame flag at bit 10,
//! the labels skipping as SMPTE 12M says). A thread writes it into a FIFO in real time, 10 ms
//! at a time, each chunk just after it "played" on the test's clock (CLOCK_MONOTONIC, as
//! frond's): read by frondd directly (`--ltc FIFO`, 25 fps) or as the capture of an ALSA device
//! (`--ltc alsa:NAME`, 29.97 drop-frame), whose takes then export drop-frame labels.

use std::io::Write;
use std::os::unix::ffi::OsStrExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use frond_e2e::{Daemon, bin, wait_for};

const RATE_HZ: usize = 48_000;

/// An LTC frame rate as the test's encoder makes it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ltc {
    /// Labels per second.
    nominal: usize,
    /// 29.97 drop-frame (frames of 1001/30000 s; labels :00 and :01 skipped in every minute
    /// not a multiple of ten).
    drop_frame: bool,
    /// Frames of 1001/30000 s (29.97, drop-frame or not).
    ntsc: bool,
}

pub(crate) const PAL: Ltc = Ltc { nominal: 25, drop_frame: false, ntsc: false };
const NTSC_DF: Ltc = Ltc { nominal: 30, drop_frame: true, ntsc: true };
const FILM: Ltc = Ltc { nominal: 24, drop_frame: false, ntsc: false };
const NTSC_30: Ltc = Ltc { nominal: 30, drop_frame: false, ntsc: false };
/// 29.97 non-drop-frame: 30's labels, frames of 1001/30000 s.
const NTSC_NDF: Ltc = Ltc { nominal: 30, drop_frame: false, ntsc: true };

impl Ltc {
    /// Seconds a frame lasts.
    fn frame_s(self) -> f64 {
        if self.ntsc { 1001.0 / 30_000.0 } else { 1.0 / self.nominal as f64 }
    }

    /// The label (h, m, s, f) of frame `count` since midnight; at drop-frame the labels
    /// skipped are added back: 17,982 frames per ten minutes, 1,798 in a minute after its
    /// first (SMPTE 12M).
    fn label_parts(self, count: usize) -> (usize, usize, usize, usize) {
        let labels = if self.drop_frame {
            let (tens, rest) = (count / 17_982, count % 17_982);
            count + 18 * tens + if rest >= 2 { 2 * ((rest - 2) / 1_798) } else { 0 }
        } else {
            count
        };
        let s = labels / self.nominal;
        (s / 3600 % 24, s / 60 % 60, s % 60, labels % self.nominal)
    }

    /// The label of frame `count`, `;` before a drop-frame label's frames.
    fn label(self, count: usize) -> String {
        let (h, m, s, f) = self.label_parts(count);
        let sep = if self.drop_frame { ';' } else { ':' };
        format!("{h:02}:{m:02}:{s:02}{sep}{f:02}")
    }

    /// Frames since midnight of a label `HH:MM:SS:FF` (or `;FF`).
    fn frames_of(self, tc: &str) -> usize {
        let p: Vec<usize> = tc.split([':', ';']).map(|x| x.parse().unwrap()).collect();
        let minutes = p[0] * 60 + p[1];
        let labels = (minutes * 60 + p[2]) * self.nominal + p[3];
        if self.drop_frame { labels - 2 * (minutes - minutes / 10) } else { labels }
    }

    /// 10:00:00:00 (10:00:00;00), in frames since midnight.
    fn start_frame(self) -> usize {
        if self.ntsc && !self.drop_frame {
            return 10 * 3600 * self.nominal; // whole-frame labels: 30 to a labelled second
        }
        (10.0 * 3600.0 / self.frame_s()).round() as usize
    }

    /// The 80 bits of frame `count` since midnight, in transmission order.
    fn frame_bits(self, count: usize) -> [bool; 80] {
        let (hour, min, sec, f) = self.label_parts(count);
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
        bits[10] = self.drop_frame;
        for (i, c) in "0011111111111101".chars().enumerate() {
            bits[64 + i] = c == '1';
        }
        // The polarity-correction bit makes the number of ones even: bit 59 at 25 fps, bit 27
        // at 24 and 30 (29.97).
        let parity = if self.nominal == 25 { 59 } else { 27 };
        bits[parity] = bits.iter().filter(|&&b| b).count() % 2 == 1;
        bits
    }
}

/// Biphase-mark samples, bit after bit: a bit of a frame of `frame_s` seconds lasts
/// `RATE_HZ * frame_s / 80` samples (20.02 at 29.97), so bit `n` of the stream starts at
/// sample `floor(n * that)`.
struct Encoder {
    ltc: Ltc,
    level: i16,
    bit_no: u64,
}

impl Encoder {
    fn frame(&mut self, count: usize, out: &mut Vec<i16>) {
        let per_bit = RATE_HZ as f64 * self.ltc.frame_s() / 80.0;
        for bit in self.ltc.frame_bits(count) {
            let start = (self.bit_no as f64 * per_bit) as u64;
            let len = ((self.bit_no + 1) as f64 * per_bit) as u64 - start;
            self.bit_no += 1;
            self.level = -self.level;
            for i in 0..len {
                if bit && i == len / 2 {
                    self.level = -self.level;
                }
                out.push(self.level);
            }
        }
    }
}

/// Writes LTC from 10:00:00:00 into `fifo` in real time until `stop`; returns when the first
/// sample played (sample `s` plays at that instant plus `s` / 48000 s).
pub(crate) fn play(ltc: Ltc, fifo: &Path, stop: Arc<AtomicBool>) -> (std::thread::JoinHandle<()>, Instant) {
    let (tx, rx) = std::sync::mpsc::channel();
    let fifo = fifo.to_path_buf();
    let handle = std::thread::spawn(move || {
        let mut out = std::fs::OpenOptions::new().write(true).open(&fifo).expect("open the FIFO to write");
        let t0 = Instant::now();
        tx.send(t0).unwrap();
        let mut encoder = Encoder { ltc, level: 12_000, bit_no: 0 };
        let (mut frame, mut pending) = (ltc.start_frame(), Vec::new());
        let chunk = RATE_HZ / 100;
        for c in 0.. {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            while pending.len() < chunk {
                encoder.frame(frame, &mut pending);
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

pub(crate) fn mkfifo(path: &Path) {
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
    let (writer, t0) = play(PAL, &fifo, stop.clone());
    locks_and_stamps_a_take(&daemon, PAL, t0);
    writer_leaves(&daemon, stop, writer);
}

/// The other rates a stage runs at (25 and 29.97 drop-frame are above): each its own daemon.
/// 29.97 non-drop-frame has 30's labels; the stage says so (`ltc.fps = "29.97"`), and the
/// frames are counted 0.1 % slower.
#[test]
fn takes_carry_the_stage_timecode_at_24_30_and_29_97_non_drop_fps() {
    for ltc in [FILM, NTSC_30, NTSC_NDF] {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("ltc.fifo");
        mkfifo(&fifo);
        let config = dir.path().join("frondd.toml");
        let declared = if ltc.ntsc { "fps = \"29.97\"\n" } else { "" };
        let input = fifo.to_str().unwrap();
        std::fs::write(&config, format!("[ltc]\ninput = \"{input}\"\n{declared}")).unwrap();
        let daemon =
            Daemon::start(dir.path(), &["--source", "in-process", "--config", config.to_str().unwrap()]);
        let stop = Arc::new(AtomicBool::new(false));
        let (writer, t0) = play(ltc, &fifo, stop.clone());
        locks_and_stamps_a_take(&daemon, ltc, t0);
        stop.store(true, Ordering::Relaxed);
        writer.join().unwrap();
    }
}

/// A private directory with a FIFO and, in its `.asoundrc`, the ALSA PCM `frondltc`: ALSA's
/// `file` plugin whose captured samples are what is written into the FIFO (the daemon's `HOME`
/// is that directory, so its libasound reads the file as an operator's own devices are read).
fn alsa_pcm_over_a_fifo() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("ltc.fifo");
    mkfifo(&fifo);
    let asoundrc = format!(
        "pcm.frondltc {{\n    type file\n    slave.pcm \"null\"\n    file \"/dev/null\"\n    infile \"{}\"\n    format \"raw\"\n}}\n",
        fifo.display()
    );
    std::fs::write(dir.path().join(".asoundrc"), asoundrc).unwrap();
    (dir, fifo)
}

/// `frondd --ltc alsa:frondltc` with `HOME` at `dir` (see [`alsa_pcm_over_a_fifo`]).
fn start_on_alsa_pcm(dir: &Path, stderr: Stdio) -> Daemon {
    let mut frondd = Command::new(bin("frondd"));
    frondd.env("HOME", dir);
    Daemon::start_command(frondd, dir, &["--source", "in-process", "--ltc", "alsa:frondltc"], stderr)
}

/// LTC read from an ALSA capture device: a PCM of ALSA's `file` plugin, defined in the
/// `.asoundrc` of the daemon's `HOME` as an operator defines their devices, whose captured
/// samples come from a FIFO the test plays into in real time (the plugin reads it as the
/// device's input; no sound card here). libasound is the real one.
#[test]
fn a_take_recorded_while_ltc_plays_into_an_alsa_capture_device_carries_the_stage_timecode() {
    let (dir, fifo) = alsa_pcm_over_a_fifo();
    // The plugin opens the FIFO when the daemon opens the device at start-up: the writer
    // waits for it there.
    let stop = Arc::new(AtomicBool::new(false));
    let player = {
        let (fifo, stop) = (fifo.clone(), stop.clone());
        std::thread::spawn(move || play(NTSC_DF, &fifo, stop))
    };
    let daemon = start_on_alsa_pcm(dir.path(), Stdio::inherit());
    let (writer, t0) = player.join().unwrap();
    assert_eq!(ltc_json(&daemon)["input"], "alsa:frondltc");
    locks_and_stamps_a_take(&daemon, NTSC_DF, t0);
    writer_leaves(&daemon, stop, writer);
}

/// An ALSA input whose reads block anyway (ALSA's `file` plugin reading a pipe whose writer
/// holds it open and sends nothing) does not keep the daemon from stopping.
#[test]
fn a_stalled_alsa_input_does_not_keep_the_daemon_from_stopping() {
    let (dir, fifo) = alsa_pcm_over_a_fifo();
    // The writer opens the pipe (the plugin's open waits for it) and then says nothing.
    let (done, wait_done) = std::sync::mpsc::channel::<()>();
    let holder = {
        let fifo = fifo.clone();
        std::thread::spawn(move || {
            let pipe = std::fs::OpenOptions::new().write(true).open(&fifo).unwrap();
            let _ = wait_done.recv_timeout(Duration::from_secs(20));
            drop(pipe);
        })
    };
    let log = dir.path().join("frondd.log");
    let mut daemon = start_on_alsa_pcm(dir.path(), std::fs::File::create(&log).unwrap().into());
    std::thread::sleep(Duration::from_millis(300));
    let pid = daemon.proc.child.id() as libc::pid_t;
    // SAFETY: plain kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
    let stopped = wait_for(Duration::from_secs(5), || daemon.proc.child.try_wait().unwrap().is_some());
    assert!(stopped, "frondd still running 5 s after SIGTERM with its LTC input stalled");
    let said = std::fs::read_to_string(&log).unwrap();
    assert!(said.contains("did not stop within 1 s (its input's read blocks); leaving it"), "{said}");
    done.send(()).unwrap();
    holder.join().unwrap();
}

/// Waits for the lock at `ltc`'s rate, records a second and checks the take's timecode, exported
/// at the stage's rate, is what played (from `t0`, when the first sample played), frame for
/// frame in the stage's labels.
fn locks_and_stamps_a_take(daemon: &Daemon, ltc: Ltc, t0: Instant) {
    let (fps_word, export_fps) = match (ltc.nominal, ltc.drop_frame) {
        (30, true) => ("29.97df", "29.97"),
        (30, false) if ltc.ntsc => ("29.97", "29.97"),
        (24, _) => ("24", "24"),
        (25, _) => ("25", "25"),
        _ => ("30", "30"),
    };
    let mut last = serde_json::Value::Null;
    let locked = wait_for(Duration::from_secs(5), || {
        last = ltc_json(daemon);
        last["state"] == "locked"
    });
    assert!(locked, "no lock: {last}");
    assert_eq!(last["fps"], fps_word, "{last}");
    let text = daemon.frond_ok(&["status"]);
    assert!(text.contains(&format!("ltc          locked at {fps_word} fps from ")), "{text}");
    assert!(!doctor(daemon).contains("stage timecode"), "a locked input is no problem");

    // What the test's clock says was playing just before and just after the take started.
    let playing =
        |at: Instant| ltc.start_frame() + (at.duration_since(t0).as_secs_f64() / ltc.frame_s()) as usize;
    let before = Instant::now();
    daemon.frond_ok(&["record", "start", "staged"]);
    let after = Instant::now();
    std::thread::sleep(Duration::from_millis(1000));
    daemon.frond_ok(&["record", "stop"]);
    let lines = daemon.frond_ok(&["take", "export", "staged", "--fps", export_fps, "--timecode"]);
    let tcs: Vec<String> = lines
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["tc"].as_str().unwrap().to_string())
        .collect();
    let got = ltc.frames_of(&tcs[0]);
    let (lo, hi) = (playing(before), playing(after));
    assert!(
        got + 1 >= lo && got <= hi + 1,
        "the take starts at {} ({got}); the LTC playing then was {} to {} ({lo}..={hi})",
        tcs[0],
        ltc.label(lo),
        ltc.label(hi)
    );
    assert!(
        tcs.iter().all(|tc| *tc == ltc.label(ltc.frames_of(tc))),
        "labels as the stage writes them: {tcs:?}"
    );
    assert!(tcs[0].starts_with("10:00:0"), "{tcs:?}");
    assert!(tcs.windows(2).all(|w| ltc.frames_of(&w[1]) == ltc.frames_of(&w[0]) + 1), "{tcs:?}");
    let per_s = 1.0 / ltc.frame_s();
    assert!(
        (0.8 * per_s..=2.0 * per_s).contains(&(tcs.len() as f64)),
        "about a second of frames: {}",
        tcs.len()
    );
}

/// The writer goes away: the lock is lost (and says so), and doctor warns.
fn writer_leaves(daemon: &Daemon, stop: Arc<AtomicBool>, writer: std::thread::JoinHandle<()>) {
    let mut last = serde_json::Value::Null;
    stop.store(true, Ordering::Relaxed);
    writer.join().unwrap();
    let lost = wait_for(Duration::from_secs(5), || {
        last = ltc_json(daemon);
        last["state"] == "lost"
    });
    assert!(lost, "the lock outlived its signal: {last}");
    assert!(last["losses"].as_u64().unwrap() >= 1 && last["frames"].as_u64().unwrap() > 25, "{last}");
    let said = doctor(daemon);
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
    let err = refused(dir.path(), &["--ltc", "alsa:frond_no_such_pcm"]);
    assert!(err.contains("ltc input: cannot open ALSA capture device \"frond_no_such_pcm\": "), "{err}");
    let err = refused(dir.path(), &["--ltc", "alsa:hw 0"]);
    assert!(err.contains("ltc.input: the ALSA device name has \" \" in it"), "{err}");
    let config = dir.path().join("frondd.toml");
    std::fs::write(&config, "[ltc]\ninput = \"/dev/null\"\nfps = \"31\"\nsample_rate_hz = 1\n").unwrap();
    let err = refused(dir.path(), &["--config", config.to_str().unwrap()]);
    assert!(err.contains("ltc.sample_rate_hz: 1 is out of range 8000..=192000"), "{err}");
    assert!(err.contains("ltc.fps: \"31\" is not one of 24, 25, 29.97df, 29.97, 30"), "{err}");
}
