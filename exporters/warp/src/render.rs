//! Offline rendering: `frond-warp render ... --frames N --fps F -o out.gif|out.webp|DIR/`.
//!
//! The wind comes from a recorded take (the root joint through [`crate::wind::HandWind`], frame
//! times from the take's pose times), from seed 003's simulation wind ([`crate::wind::SimWind`])
//! or, without either, from the seeded procedural wind. Either way the output depends only on the
//! inputs and the seed.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame, RgbaImage};
use thiserror::Error;

mod output;

use crate::compose::Animator;
use crate::wind::{HandWind, SimWind};
use frond_formats::rig_files::AtomicOutput;
use output::{GifWriter, frames_dir};

/// What blows the picture in an offline render.
#[derive(Debug, Clone, Copy)]
pub enum WindDriver<'a> {
    /// The seeded procedural wind of the parameters.
    Procedural,
    /// A take's root joint, as the hand live (looping if the take is shorter).
    Take(&'a PoseTrack),
    /// The simulation's wind at each frame's time.
    Sim(&'a SimWind),
}

/// Where frames go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OutputKind {
    /// An animated GIF.
    Gif(PathBuf),
    /// An animated, lossless WebP.
    Webp(PathBuf),
    /// A directory of `frame_00000.png`...
    Dir(PathBuf),
}

/// Errors of rendering.
#[derive(Debug, Error)]
pub enum RenderError {
    /// The output name says neither .gif, .webp nor a directory.
    #[error("output {0} must end in .gif or .webp, or be a directory (end it with /)")]
    UnknownOutput(PathBuf),
    /// Writing failed.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Encoding failed.
    #[error("cannot encode {path}: {source}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// Why.
        source: image::ImageError,
    },
    /// The take could not be read.
    #[error("cannot read take {path}: {message}")]
    Take {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

impl OutputKind {
    /// Checks where the output goes before anything is rendered, as
    /// [`frond_formats::rig_files::output_destination`] does for every file frond writes: a GIF
    /// or WebP is a regular file (or a new one in a directory that exists), never a FIFO (the
    /// render would hang on it), a device or a directory; a directory of frames is a directory,
    /// or a new one whose parent exists (a mistyped path is not made into a tree).
    pub fn check_destination(&self) -> Result<(), RenderError> {
        let refused = |path: &Path, source| RenderError::Write { path: path.to_path_buf(), source };
        match self {
            OutputKind::Gif(path) | OutputKind::Webp(path) => {
                frond_formats::rig_files::output_destination(path).map(|_| ()).map_err(|e| refused(path, e))
            }
            OutputKind::Dir(path) => frames_dir(path, false).map_err(|e| refused(path, e)),
        }
    }

    /// Classifies `-o`: `.gif`, `.webp`, or a directory (trailing `/` or existing directory).
    pub fn from_path(path: &Path) -> Result<OutputKind, RenderError> {
        let s = path.to_string_lossy();
        if s.ends_with('/') || path.is_dir() {
            return Ok(OutputKind::Dir(path.to_path_buf()));
        }
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("gif") => Ok(OutputKind::Gif(path.to_path_buf())),
            Some("webp") => Ok(OutputKind::Webp(path.to_path_buf())),
            _ => Err(RenderError::UnknownOutput(path.to_path_buf())),
        }
    }
}

/// Root-joint rotations over time (seconds from the first pose).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseTrack {
    /// Times, seconds, non-decreasing.
    pub times_s: Vec<f64>,
    /// Root joint `[pitch, yaw, roll]` at each time, degrees.
    pub roots_deg: Vec<[f32; 3]>,
    /// Every joint at each time, degrees (the cage mode skins the crown with them).
    pub joints_deg: Vec<[[f32; 3]; 4]>,
    /// The rig the take was recorded with (its header's).
    pub rig_name: Option<String>,
    /// What the reader skipped in a damaged take, in words (`None` when it is sound): the track
    /// holds the readable frames.
    pub damage: Option<String>,
}

impl PoseTrack {
    /// Reads a `.take` file (frond's take format) and keeps the root joint of every frame.
    pub fn from_take(path: &Path) -> Result<PoseTrack, RenderError> {
        let bytes = frond_formats::rig_files::read_take_file(path)
            .map_err(|e| RenderError::Take { path: path.to_path_buf(), message: e.reason() })?;
        let scan = frond_formats::take::scan_take(&bytes)
            .map_err(|e| RenderError::Take { path: path.to_path_buf(), message: e.to_string() })?;
        let poses = scan.poses();
        if poses.is_empty() {
            return Err(RenderError::Take {
                path: path.to_path_buf(),
                message: "the take has no frames".into(),
            });
        }
        let t0 = poses[0].t;
        Ok(PoseTrack {
            times_s: poses.iter().map(|p| p.t - t0).collect(),
            roots_deg: poses.iter().map(|p| p.joints_deg[0]).collect(),
            joints_deg: poses.iter().map(|p| p.joints_deg).collect(),
            rig_name: scan.header.as_ref().map(|h| h.rig_name.clone()),
            damage: scan.damage(),
        })
    }
}

/// Progress on stderr: a bar on a terminal, nothing otherwise (or when quiet).
pub(crate) struct Progress {
    total: usize,
    on: bool,
}

impl Progress {
    pub(crate) fn new(total: usize, quiet: bool) -> Progress {
        Progress { total, on: !quiet && std::io::stderr().is_terminal() }
    }
    pub(crate) fn tick(&self, done: usize) {
        if !self.on {
            return;
        }
        let width = 30;
        let filled = done * width / self.total.max(1);
        let mut err = std::io::stderr().lock();
        let _ = write!(
            err,
            "\r[{}{}] {done}/{} frames",
            "#".repeat(filled),
            ".".repeat(width - filled),
            self.total
        );
        if done == self.total {
            let _ = writeln!(err);
        }
        let _ = err.flush();
    }
}

/// Renders `frames` frames at `fps` into `out`, blown by `driver`. Returns the number of frames
/// written.
pub fn render(
    animator: &mut Animator,
    driver: WindDriver<'_>,
    frames: usize,
    fps: f32,
    out: &OutputKind,
    quiet: bool,
) -> Result<usize, RenderError> {
    let dt = 1.0 / fps;
    let (w, h) = (animator.scene().width, animator.scene().height);
    let progress = Progress::new(frames, quiet);
    let mut hand = HandWind::new();
    let mut cursor = 0usize;
    let mut sink = Sink::open(out, w, h, fps)?;
    if !matches!(driver, WindDriver::Procedural) {
        animator.set_procedural(false);
    }
    for k in 0..frames {
        if let WindDriver::Sim(sim) = driver {
            let mut wind = animator.params().wind;
            sim.update(k as f64 * dt as f64, &mut wind);
            // Valid by construction (direction finite, strength clamped, interval 0).
            let _ = animator.set_wind(wind);
        }
        if let WindDriver::Take(tr) = driver {
            let duration = tr.times_s.last().copied().unwrap_or(0.0).max(1e-9);
            let t = (k as f64 * dt as f64) % (duration + dt as f64);
            if k > 0 && cursor < tr.times_s.len() && tr.times_s[cursor] > t {
                cursor = 0; // looped
            }
            let mut wind = animator.params().wind;
            while cursor < tr.times_s.len() && tr.times_s[cursor] <= t {
                hand.update(k as f64 * dt as f64, tr.roots_deg[cursor], &mut wind);
                cursor += 1;
            }
            // Settings from a take are valid by construction (clamped strength and interval).
            let _ = animator.set_wind(wind);
        }
        let frame = animator.step(dt);
        sink.push(k, frame)?;
        progress.tick(k + 1);
    }
    sink.finish()?;
    Ok(frames)
}

/// Where rendered frames go (GIF, animated WebP or a directory of PNGs).
pub(crate) enum Sink {
    Gif(PathBuf, Box<GifEncoder<GifWriter>>, GifWriter, AtomicOutput, u32, u32, Delay),
    Webp(PathBuf, WebpAnim),
    Dir(PathBuf, u32, u32),
}

impl Sink {
    pub(crate) fn open(out: &OutputKind, w: usize, h: usize, fps: f32) -> Result<Sink, RenderError> {
        let (w, h) = (w as u32, h as u32);
        out.check_destination()?;
        Ok(match out {
            OutputKind::Gif(path) => {
                let write_err = |source| RenderError::Write { path: path.clone(), source };
                let mut tmp = AtomicOutput::create(path).map_err(write_err)?;
                // The encoder owns its writer: a second handle on the temporary file.
                let writer = GifWriter::new(tmp.file().try_clone().map_err(write_err)?);
                let mut enc = GifEncoder::new_with_speed(writer.clone(), 10);
                enc.set_repeat(Repeat::Infinite)
                    .map_err(|source| RenderError::Encode { path: path.clone(), source })?;
                let delay = Delay::from_numer_denom_ms(1000, fps.round().max(1.0) as u32);
                Sink::Gif(path.clone(), Box::new(enc), writer, tmp, w, h, delay)
            }
            OutputKind::Webp(path) => {
                Sink::Webp(path.clone(), WebpAnim::new(w, h, (1000.0 / fps).round() as u32))
            }
            OutputKind::Dir(path) => {
                frames_dir(path, true).map_err(|source| RenderError::Write { path: path.clone(), source })?;
                Sink::Dir(path.clone(), w, h)
            }
        })
    }

    pub(crate) fn push(&mut self, k: usize, frame: &[u8]) -> Result<(), RenderError> {
        match self {
            Sink::Gif(path, enc, _, _, w, h, delay) => {
                let img = RgbaImage::from_raw(*w, *h, frame.to_vec()).expect("frame size");
                enc.encode_frame(Frame::from_parts(img, 0, 0, *delay))
                    .map_err(|source| RenderError::Encode { path: path.clone(), source })
            }
            Sink::Webp(path, anim) => {
                anim.push(frame).map_err(|source| RenderError::Encode { path: path.clone(), source })
            }
            Sink::Dir(dir, w, h) => {
                let path = dir.join(format!("frame_{k:05}.png"));
                let mut png = Vec::new();
                image::ImageEncoder::write_image(
                    image::codecs::png::PngEncoder::new(&mut png),
                    frame,
                    *w,
                    *h,
                    image::ExtendedColorType::Rgba8,
                )
                .map_err(|source| RenderError::Encode { path: path.clone(), source })?;
                frond_formats::rig_files::write_file_atomically(&path, &png)
                    .map_err(|source| RenderError::Write { path, source })
            }
        }
    }

    pub(crate) fn finish(self) -> Result<(), RenderError> {
        match self {
            Sink::Dir(..) => Ok(()),
            Sink::Gif(path, enc, writer, tmp, ..) => {
                // The encoder writes the GIF trailer when dropped; then the file is complete.
                drop(enc);
                writer
                    .finish()
                    .and_then(|file| {
                        drop(file);
                        tmp.persist()
                    })
                    .map_err(|source| RenderError::Write { path, source })
            }
            Sink::Webp(path, anim) => frond_formats::rig_files::write_file_atomically(&path, &anim.finish())
                .map_err(|source| RenderError::Write { path, source }),
        }
    }
}

/// An animated WebP assembled from lossless (VP8L) frames: `RIFF/WEBP` with `VP8X`, `ANIM` and
/// one `ANMF` chunk per frame (the WebP container specification).
pub struct WebpAnim {
    w: u32,
    h: u32,
    duration_ms: u32,
    frames: Vec<u8>,
}

impl WebpAnim {
    /// An empty animation of `w x h` with `duration_ms` per frame.
    pub fn new(w: u32, h: u32, duration_ms: u32) -> WebpAnim {
        WebpAnim { w, h, duration_ms: duration_ms.clamp(1, 0xFF_FFFF), frames: Vec::new() }
    }

    /// Encodes one RGBA frame.
    pub fn push(&mut self, rgba: &[u8]) -> Result<(), image::ImageError> {
        let mut single = Vec::new();
        image::codecs::webp::WebPEncoder::new_lossless(&mut single).encode(
            rgba,
            self.w,
            self.h,
            image::ExtendedColorType::Rgba8,
        )?;
        // Find the VP8L chunk of the single-image file (after "RIFF" size "WEBP").
        let mut pos = 12;
        let mut bitstream = None;
        while pos + 8 <= single.len() {
            let id = &single[pos..pos + 4];
            let len = u32::from_le_bytes(single[pos + 4..pos + 8].try_into().expect("4 bytes")) as usize;
            let end = (pos + 8 + len).min(single.len());
            if id == b"VP8L" {
                bitstream = Some(single[pos..end].to_vec());
                break;
            }
            pos = pos + 8 + len + (len & 1);
        }
        let chunk = bitstream.ok_or_else(|| {
            image::ImageError::IoError(std::io::Error::other("webp encoder produced no VP8L chunk"))
        })?;
        let mut payload = Vec::with_capacity(chunk.len() + 16);
        payload.extend_from_slice(&[0, 0, 0, 0, 0, 0]); // frame x/2, y/2 = 0
        payload.extend_from_slice(&u24(self.w - 1));
        payload.extend_from_slice(&u24(self.h - 1));
        payload.extend_from_slice(&u24(self.duration_ms));
        payload.push(0b10); // no blending, no disposal
        payload.extend_from_slice(&chunk);
        if chunk.len() % 2 == 1 {
            payload.push(0);
        }
        push_chunk(&mut self.frames, b"ANMF", &payload);
        Ok(())
    }

    /// The complete file.
    pub fn finish(self) -> Vec<u8> {
        let mut body = Vec::new();
        body.extend_from_slice(b"WEBP");
        let mut vp8x = vec![0b0001_0010, 0, 0, 0]; // alpha + animation
        vp8x.extend_from_slice(&u24(self.w - 1));
        vp8x.extend_from_slice(&u24(self.h - 1));
        push_chunk(&mut body, b"VP8X", &vp8x);
        push_chunk(&mut body, b"ANIM", &[0, 0, 0, 0, 0, 0]); // background, loop forever
        body.extend_from_slice(&self.frames);
        let mut out = Vec::with_capacity(body.len() + 8);
        out.extend_from_slice(b"RIFF");
        out.extend_from_slice(&(body.len() as u32).to_le_bytes());
        out.extend_from_slice(&body);
        out
    }
}

fn u24(v: u32) -> [u8; 3] {
    let b = v.to_le_bytes();
    [b[0], b[1], b[2]]
}

fn push_chunk(out: &mut Vec<u8>, id: &[u8; 4], payload: &[u8]) {
    out.extend_from_slice(id);
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(payload);
    if payload.len() % 2 == 1 {
        out.push(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_kinds() {
        assert!(matches!(OutputKind::from_path(Path::new("a.GIF")), Ok(OutputKind::Gif(_))));
        assert!(matches!(OutputKind::from_path(Path::new("a.webp")), Ok(OutputKind::Webp(_))));
        assert!(matches!(OutputKind::from_path(Path::new("frames/")), Ok(OutputKind::Dir(_))));
        let err = OutputKind::from_path(Path::new("a.mp4")).unwrap_err().to_string();
        assert!(err.contains("a.mp4") && err.contains(".gif"), "{err}");
    }

    #[test]
    fn a_gif_appears_whole_when_finished_and_not_at_all_when_abandoned() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.gif");
        let listing = || -> Vec<std::ffi::OsString> {
            std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect()
        };
        let frame: Vec<u8> = (0..4 * 3 * 4).map(|i| (i * 5) as u8).collect();
        // Abandoned (a render that failed): no file, no temporary file.
        let mut sink = Sink::open(&OutputKind::Gif(path.clone()), 4, 3, 10.0).unwrap();
        sink.push(0, &frame).unwrap();
        assert!(!path.exists(), "the destination is written only when the render is done");
        drop(sink);
        assert_eq!(listing(), Vec::<std::ffi::OsString>::new());
        // An old file is kept until the new one is whole, then replaced, its mode kept.
        use std::os::unix::fs::PermissionsExt;
        std::fs::write(&path, b"old").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
        let mut sink = Sink::open(&OutputKind::Gif(path.clone()), 4, 3, 10.0).unwrap();
        sink.push(0, &frame).unwrap();
        sink.push(1, &frame).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        sink.finish().unwrap();
        assert_eq!(listing(), vec![std::ffi::OsString::from("a.gif")]);
        assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o640);
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.starts_with(b"GIF89a") && bytes.ends_with(&[0x3b]), "a whole GIF, its trailer last");
        use image::AnimationDecoder;
        let dec = image::codecs::gif::GifDecoder::new(std::io::Cursor::new(bytes)).unwrap();
        assert_eq!(dec.into_frames().count(), 2);
    }

    #[test]
    fn animated_webp_decodes_frame_by_frame() {
        let mut anim = WebpAnim::new(5, 3, 40);
        let f1: Vec<u8> = (0..60).map(|i| (i * 4) as u8).collect();
        let f2: Vec<u8> = (0..60).map(|i| 255 - (i * 4) as u8).map(|v| v | 1).collect();
        anim.push(&f1).unwrap();
        anim.push(&f2).unwrap();
        let bytes = anim.finish();
        let dec = image::codecs::webp::WebPDecoder::new(std::io::Cursor::new(bytes)).unwrap();
        use image::AnimationDecoder;
        let frames: Vec<_> = dec.into_frames().collect::<Result<_, _>>().unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].buffer().as_raw(), &f1);
        assert_eq!(frames[1].buffer().as_raw(), &f2);
    }
}
