//! LTC from an ALSA capture device (issue 46): `ltc.input = "alsa:DEVICE"`, e.g. `alsa:default`
//! or `alsa:plughw:CARD=USB,DEV=0`, read as mono signed 16-bit samples at `ltc.sample_rate_hz`.
//!
//! libasound is loaded when such an input is opened (`libasound.so.2`, which every desktop
//! Linux has), not linked: building frond needs no ALSA headers, and a daemon that reads no LTC
//! from a sound card never touches it. Only the few calls a capture needs are bound, with the
//! signatures of alsa-lib's `pcm.h`; `snd_pcm_set_params` asks for the format, one channel and
//! the rate, and lets ALSA's plug layer convert (a `hw:` device that cannot is refused at
//! start-up with ALSA's words and a hint to use `plughw:`).
//!
//! The handle is used by the `frond-ltc` thread only (opened at start-up so a bad device fails
//! the start, then moved there). It is opened non-blocking: each read waits for the device at
//! most the thread's poll (`snd_pcm_wait`), then takes what is there, at most
//! [`CHUNK_FRAMES_MAX`] frames; an overrun (the thread fell behind) is recovered and counted; a
//! device that goes away is reopened at most once per [`REOPEN_EVERY`].

use std::ffi::{CStr, CString, c_char, c_int, c_long, c_uint, c_ulong, c_void};
use std::time::{Duration, Instant};

/// The library loaded, by its soname.
pub const LIBASOUND: &str = "libasound.so.2";

/// Most frames read at once (the thread reads 10 ms; 192 kHz * 10 ms is 1,920).
pub const CHUNK_FRAMES_MAX: usize = 4096;

/// How often a device that failed is tried again.
pub const REOPEN_EVERY: Duration = Duration::from_secs(1);

/// Longest ALSA device name taken from the configuration.
pub const MAX_DEVICE_NAME_BYTES: usize = 256;

/// The latency asked of the device, microseconds: its buffer, which rides out a late thread.
const LATENCY_US: c_uint = 200_000;

// alsa-lib's pcm.h: SND_PCM_STREAM_CAPTURE, SND_PCM_FORMAT_S16_LE, SND_PCM_ACCESS_RW_INTERLEAVED.
const SND_PCM_STREAM_CAPTURE: c_int = 1;
const SND_PCM_FORMAT_S16_LE: c_int = 2;
const SND_PCM_ACCESS_RW_INTERLEAVED: c_int = 3;
// pcm.h's SND_PCM_NONBLOCK open mode.
const SND_PCM_NONBLOCK: c_int = 1;

/// Why an ALSA capture could not be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AlsaError {
    /// libasound could not be loaded.
    #[error(
        "cannot load {LIBASOUND} ({why}); reading LTC from a sound card needs ALSA's library (Debian: apt-get install libasound2)"
    )]
    NoLibrary {
        /// The loader's words.
        why: String,
    },
    /// The device name is not one frond passes to ALSA.
    #[error("{0}")]
    BadName(String),
    /// ALSA refused to open the device.
    #[error("cannot open ALSA capture device {device:?}: {why}")]
    Open {
        /// The device name.
        device: String,
        /// ALSA's words.
        why: String,
    },
    /// The device does not take the format, channel count or rate.
    #[error(
        "ALSA capture device {device:?} cannot give mono 16-bit samples at {rate_hz} Hz: {why} (a `plughw:` or `default` device converts)"
    )]
    Params {
        /// The device name.
        device: String,
        /// The rate asked.
        rate_hz: u32,
        /// ALSA's words.
        why: String,
    },
    /// A read failed and could not be recovered.
    #[error("reading ALSA capture device {device:?}: {why}")]
    Read {
        /// The device name.
        device: String,
        /// ALSA's words.
        why: String,
    },
}

/// Checks a device name from the configuration: not empty, at most [`MAX_DEVICE_NAME_BYTES`],
/// printable ASCII (ALSA's names are `hw:1,0`, `plughw:CARD=USB,DEV=0`, `default`, `pcm.NAME`).
pub fn check_device_name(name: &str) -> Result<(), AlsaError> {
    if name.is_empty() {
        return Err(AlsaError::BadName(
            "alsa: needs a device name, e.g. alsa:default or alsa:plughw:1,0".into(),
        ));
    }
    if name.len() > MAX_DEVICE_NAME_BYTES {
        return Err(AlsaError::BadName(format!(
            "an ALSA device name of {} bytes (at most {MAX_DEVICE_NAME_BYTES})",
            name.len()
        )));
    }
    if let Some(c) = name.chars().find(|c| !c.is_ascii_graphic()) {
        return Err(AlsaError::BadName(format!(
            "the ALSA device name has {:?} in it (names are printable ASCII without spaces)",
            c.escape_default().to_string()
        )));
    }
    Ok(())
}

type SndPcm = c_void;

/// The entry points used, from the loaded library.
struct Api {
    open: unsafe extern "C" fn(*mut *mut SndPcm, *const c_char, c_int, c_int) -> c_int,
    set_params: unsafe extern "C" fn(*mut SndPcm, c_int, c_int, c_uint, c_uint, c_int, c_uint) -> c_int,
    readi: unsafe extern "C" fn(*mut SndPcm, *mut c_void, c_ulong) -> c_long,
    recover: unsafe extern "C" fn(*mut SndPcm, c_int, c_int) -> c_int,
    wait: unsafe extern "C" fn(*mut SndPcm, c_int) -> c_int,
    avail_update: unsafe extern "C" fn(*mut SndPcm) -> c_long,
    get_params: unsafe extern "C" fn(*mut SndPcm, *mut c_ulong, *mut c_ulong) -> c_int,
    close: unsafe extern "C" fn(*mut SndPcm) -> c_int,
    strerror: unsafe extern "C" fn(c_int) -> *const c_char,
    /// Keeps the functions above valid.
    _library: libloading::Library,
}

impl Api {
    fn load() -> Result<Api, AlsaError> {
        let no_library = |e: libloading::Error| AlsaError::NoLibrary { why: e.to_string() };
        // SAFETY: loading libasound runs its initialisers, which have no preconditions; the
        // library stays loaded as long as `Api` (it owns the `Library`).
        let library = unsafe { libloading::Library::new(LIBASOUND) }.map_err(no_library)?;
        // SAFETY: each symbol is looked up by its alsa-lib name and given the type of its
        // declaration in alsa-lib's pcm.h / error.h (snd_pcm_sframes_t and snd_pcm_uframes_t
        // are long and unsigned long on Linux); the pointers are copied out while `library`
        // is alive and kept beside it in `Api`.
        unsafe {
            Ok(Api {
                open: *library.get(b"snd_pcm_open\0").map_err(no_library)?,
                set_params: *library.get(b"snd_pcm_set_params\0").map_err(no_library)?,
                readi: *library.get(b"snd_pcm_readi\0").map_err(no_library)?,
                recover: *library.get(b"snd_pcm_recover\0").map_err(no_library)?,
                wait: *library.get(b"snd_pcm_wait\0").map_err(no_library)?,
                avail_update: *library.get(b"snd_pcm_avail_update\0").map_err(no_library)?,
                get_params: *library.get(b"snd_pcm_get_params\0").map_err(no_library)?,
                close: *library.get(b"snd_pcm_close\0").map_err(no_library)?,
                strerror: *library.get(b"snd_strerror\0").map_err(no_library)?,
                _library: library,
            })
        }
    }

    /// ALSA's words for a negative return.
    fn error_text(&self, code: c_int) -> String {
        // SAFETY: snd_strerror returns a pointer to a static NUL-terminated string for any
        // code (or NULL, checked).
        let text = unsafe { (self.strerror)(code) };
        if text.is_null() {
            return format!("error {code}");
        }
        // SAFETY: non-null, NUL-terminated and static (above).
        unsafe { CStr::from_ptr(text) }.to_string_lossy().into_owned()
    }
}

/// An open ALSA capture of mono s16le samples.
pub struct AlsaCapture {
    api: Api,
    device: String,
    rate_hz: u32,
    /// Null while the device is closed (after a failure, until reopened).
    pcm: *mut SndPcm,
    /// The device's buffer, frames (0 when ALSA did not say).
    buffer_frames: u64,
    /// When it was last tried, while closed.
    last_try: Option<Instant>,
    /// Overruns recovered (the thread fell behind the device).
    overruns: u64,
}

// SAFETY: the pcm handle is used from one thread at a time: opened at start-up, then moved
// to the frond-ltc thread, which alone reads and closes it. alsa-lib's PCM functions may be
// called from any thread as long as calls on one handle are not concurrent.
unsafe impl Send for AlsaCapture {}

impl std::fmt::Debug for AlsaCapture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AlsaCapture")
            .field("device", &self.device)
            .field("rate_hz", &self.rate_hz)
            .field("open", &!self.pcm.is_null())
            .field("overruns", &self.overruns)
            .finish()
    }
}

impl AlsaCapture {
    /// Loads libasound and opens `device` for capture: mono, s16le, `rate_hz`.
    pub fn open(device: &str, rate_hz: u32) -> Result<AlsaCapture, AlsaError> {
        check_device_name(device)?;
        let api = Api::load()?;
        let mut capture = AlsaCapture {
            api,
            device: device.to_string(),
            rate_hz,
            pcm: std::ptr::null_mut(),
            buffer_frames: 0,
            last_try: None,
            overruns: 0,
        };
        (capture.pcm, capture.buffer_frames) = capture.open_pcm()?;
        Ok(capture)
    }

    /// Opens the device and sets it up: its handle and its buffer's size in frames.
    fn open_pcm(&self) -> Result<(*mut SndPcm, u64), AlsaError> {
        let name = CString::new(self.device.as_str())
            .map_err(|_| AlsaError::BadName("the ALSA device name has a NUL in it".into()))?;
        let mut pcm: *mut SndPcm = std::ptr::null_mut();
        // SAFETY: `pcm` is a valid out-pointer and `name` a NUL-terminated string alive for
        // the call. Non-blocking: a read waits only in `snd_pcm_wait`, at most `idle`.
        let rc =
            unsafe { (self.api.open)(&mut pcm, name.as_ptr(), SND_PCM_STREAM_CAPTURE, SND_PCM_NONBLOCK) };
        if rc < 0 || pcm.is_null() {
            return Err(AlsaError::Open { device: self.device.clone(), why: self.api.error_text(rc) });
        }
        // SAFETY: `pcm` was just opened; the arguments are pcm.h's enum values.
        let rc = unsafe {
            (self.api.set_params)(
                pcm,
                SND_PCM_FORMAT_S16_LE,
                SND_PCM_ACCESS_RW_INTERLEAVED,
                1,
                self.rate_hz,
                1,
                LATENCY_US,
            )
        };
        if rc < 0 {
            let why = self.api.error_text(rc);
            // SAFETY: `pcm` is open and not used after this.
            unsafe { (self.api.close)(pcm) };
            return Err(AlsaError::Params { device: self.device.clone(), rate_hz: self.rate_hz, why });
        }
        let (mut buffer, mut period): (c_ulong, c_ulong) = (0, 0);
        // SAFETY: `pcm` is open and set up; both out-pointers are valid for the call.
        let rc = unsafe { (self.api.get_params)(pcm, &mut buffer, &mut period) };
        // c_ulong is u64 here but u32 on 32-bit targets.
        #[allow(clippy::useless_conversion)]
        let buffer = u64::from(buffer);
        Ok((pcm, if rc < 0 { 0 } else { buffer }))
    }

    /// The sample rate it was opened at, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.rate_hz
    }

    /// Overruns recovered so far.
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Reads up to `out.len()` (at most [`CHUNK_FRAMES_MAX`]) samples, waiting at most `idle`
    /// for the device: `Ok(0)` when nothing could be read this time (none came, an overrun was
    /// recovered, or the device is closed and not yet reopened, in which case it sleeps `idle`).
    pub fn read(&mut self, out: &mut [i16], idle: Duration) -> Result<usize, AlsaError> {
        if self.pcm.is_null() {
            if self.last_try.is_some_and(|t| t.elapsed() < REOPEN_EVERY) {
                std::thread::sleep(idle);
                return Ok(0);
            }
            self.last_try = Some(Instant::now());
            (self.pcm, self.buffer_frames) = self.open_pcm()?;
            self.last_try = None;
        }
        let idle_ms = c_int::try_from(idle.as_millis()).unwrap_or(c_int::MAX);
        // SAFETY: the handle is open.
        let ready = unsafe { (self.api.wait)(self.pcm, idle_ms) };
        let got = match ready {
            0 => return Ok(0),
            r if r < 0 => c_long::from(r),
            _ => {
                let frames = out.len().min(CHUNK_FRAMES_MAX);
                // SAFETY: the handle is open; `out` has room for `frames` mono s16 frames.
                let got = unsafe { (self.api.readi)(self.pcm, out.as_mut_ptr().cast(), frames as c_ulong) };
                if got >= 0 {
                    return Ok((got as usize).min(frames));
                }
                got
            }
        };
        let code = c_int::try_from(got).unwrap_or(-libc::EIO);
        if code == -libc::EAGAIN {
            return Ok(0);
        }
        // SAFETY: the handle is open; silent = 1 (no message on stderr).
        let rc = unsafe { (self.api.recover)(self.pcm, code, 1) };
        if rc >= 0 {
            if code == -libc::EPIPE {
                self.overruns += 1;
            }
            return Ok(0);
        }
        let why = self.api.error_text(code);
        self.close();
        self.last_try = Some(Instant::now());
        Err(AlsaError::Read { device: self.device.clone(), why })
    }

    /// Samples captured and not yet read (0 when unknown): the last sample read played that
    /// long before now. A full buffer says nothing of its samples' age (a device whose buffer
    /// is full is overrunning, and the next read says so; a PCM with no clock of its own, such
    /// as ALSA's `null` under a `file` plugin, always reports its whole buffer): unknown.
    pub fn queued_samples(&self) -> u64 {
        if self.pcm.is_null() {
            return 0;
        }
        // SAFETY: the handle is open.
        let avail = unsafe { (self.api.avail_update)(self.pcm) };
        match u64::try_from(avail) {
            Ok(n) if self.buffer_frames == 0 || n < self.buffer_frames => n,
            _ => 0,
        }
    }

    fn close(&mut self) {
        if !self.pcm.is_null() {
            // SAFETY: the handle is open and not used after this (set to null).
            unsafe { (self.api.close)(self.pcm) };
            self.pcm = std::ptr::null_mut();
        }
    }
}

impl Drop for AlsaCapture {
    fn drop(&mut self) {
        self.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_names_are_checked_before_alsa_sees_them() {
        assert!(check_device_name("default").is_ok());
        assert!(check_device_name("plughw:CARD=USB,DEV=0").is_ok());
        for (bad, says) in [
            ("", "needs a device name"),
            ("hw 1", "\" \""),
            ("hw:\n1", "\\\\n"),
            ("hw:\u{202e}1", "printable ASCII"),
        ] {
            let e = check_device_name(bad).unwrap_err().to_string();
            assert!(e.contains(says), "{bad:?}: {e}");
        }
        let long = "x".repeat(MAX_DEVICE_NAME_BYTES + 1);
        assert!(check_device_name(&long).unwrap_err().to_string().contains("257 bytes"));
    }
}
