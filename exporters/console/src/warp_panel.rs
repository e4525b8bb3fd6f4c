//! The seed-001 warp preview as a panel of the console: `frond-warp`'s animator (stable fluids,
//! waves, grid warping) on the sample grass picture, its wind driven by the live hand's root
//! joint (`frond_warp::wind::HandWind`, as `frond-warp serve` does) or procedural when no hand
//! moves, stepped at 30 Hz only while a page watches, each frame sent as one JPEG over a binary
//! WebSocket (a few tens of KB a frame instead of the 300 KB of raw RGBA the warp page polls).
//!
//! The defaults show visible motion at the page's size: the layer's displacement scale is four
//! times `frond-warp`'s (lambda 48 x 16 pixels) and the procedural wind blows at full strength.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use frond_warp::wind::HandWind;
use frond_warp::{Animator, InvalidParams, LayerInput, LayerParams, Scene, SceneError, SceneParams};
use serde_json::{Value, json};

use crate::relay::Live;

/// Steps per second.
pub const WARP_FPS: f32 = 30.0;
/// JPEG quality of the frames sent.
pub const JPEG_QUALITY: u8 = 80;
/// Poses older than this leave the wind procedural.
const FRESH: Duration = Duration::from_millis(500);

/// The latest frame and what drove it.
#[derive(Debug, Default)]
pub struct WarpFrame {
    /// Frame number (0: none yet).
    pub number: u64,
    /// The frame as JPEG.
    pub jpeg: Arc<Vec<u8>>,
    /// `{"frame", "width", "height", "source": "hand"|"procedural", "wind": {...}, "fps"}`.
    pub state: Value,
}

/// The panel's animator thread and its output.
#[derive(Debug, Default)]
pub struct WarpPanel {
    latest: Mutex<WarpFrame>,
    /// Pages watching; the animator sleeps when none is.
    pub viewers: AtomicUsize,
}

/// The panel's scene: the sample grass picture (320 x 240) and its matte.
pub fn sample_scene() -> Result<Scene, SceneError> {
    let (picture, mask, _scale) = frond_warp::samples::grass();
    Scene::build(picture, vec![("grass".to_string(), LayerInput::Mask(mask))], None, None)
}

/// Why the warp panel could not start.
#[derive(Debug, thiserror::Error)]
pub enum WarpPanelError {
    /// The parameters do not fit the scene.
    #[error(transparent)]
    Params(#[from] InvalidParams),
    /// The animator's thread could not be started.
    #[error(transparent)]
    Thread(#[from] std::io::Error),
}

/// The panel's parameters: visible motion at the page's size (see the module docs).
pub fn panel_params() -> SceneParams {
    let mut p = SceneParams::default();
    p.wind.strength = 1.0;
    p.layers = vec![LayerParams { lambda_x: 48.0, lambda_y: 16.0, ..LayerParams::default() }];
    p
}

impl WarpPanel {
    /// Starts the animator thread on `scene`, its wind from `live`'s element 0.
    pub fn start(
        live: Arc<Live>,
        scene: Scene,
        params: SceneParams,
    ) -> Result<Arc<WarpPanel>, WarpPanelError> {
        let animator = Animator::new(scene, params)?;
        let panel = Arc::new(WarpPanel::default());
        let me = Arc::clone(&panel);
        std::thread::Builder::new().name("console-warp".into()).spawn(move || me.run(animator, &live))?;
        Ok(panel)
    }

    /// The latest frame (number, JPEG, state).
    pub fn latest(&self) -> (u64, Arc<Vec<u8>>, Value) {
        let f = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        (f.number, Arc::clone(&f.jpeg), f.state.clone())
    }

    fn run(&self, mut animator: Animator, live: &Live) {
        let dt = 1.0 / WARP_FPS;
        let period = Duration::from_secs_f32(dt);
        let (w, h) = (animator.scene().width, animator.scene().height);
        let mut hand = HandWind::new();
        let start = Instant::now();
        let mut next = Instant::now();
        let (mut number, mut window, mut window_frames, mut fps) = (0u64, Instant::now(), 0u32, 0.0f32);
        let mut rgb = vec![0u8; w * h * 3];
        loop {
            if self.viewers.load(Ordering::Relaxed) == 0 {
                std::thread::sleep(Duration::from_millis(100));
                next = Instant::now();
                continue;
            }
            let root = live.root_pose(FRESH);
            let source = if let Some(root_deg) = root {
                animator.set_procedural(false);
                let mut wind = animator.params().wind;
                hand.update(start.elapsed().as_secs_f64(), root_deg, &mut wind);
                let _ = animator.set_wind(wind);
                "hand"
            } else {
                animator.set_procedural(true);
                "procedural"
            };
            let frame = animator.step(dt);
            for (o, i) in rgb.chunks_exact_mut(3).zip(frame.chunks_exact(4)) {
                o.copy_from_slice(&i[..3]);
            }
            let mut jpeg = Vec::with_capacity(32 * 1024);
            let encoded = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, JPEG_QUALITY).encode(
                &rgb,
                w as u32,
                h as u32,
                image::ExtendedColorType::Rgb8,
            );
            number += 1;
            window_frames += 1;
            if window.elapsed() >= Duration::from_secs(1) {
                fps = window_frames as f32 / window.elapsed().as_secs_f32();
                (window, window_frames) = (Instant::now(), 0);
            }
            if encoded.is_ok() {
                let wind = animator.params().wind;
                let state = json!({
                    "frame": number, "width": w, "height": h, "source": source, "fps": fps,
                    "wind": { "direction_deg": wind.direction_deg, "strength": wind.strength, "interval_s": wind.interval_s },
                });
                *self.latest.lock().unwrap_or_else(|e| e.into_inner()) =
                    WarpFrame { number, jpeg: Arc::new(jpeg), state };
            }
            crate::pace(&mut next, period);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sample_scene_and_the_panel_params_are_valid() {
        let scene = sample_scene().unwrap();
        assert_eq!((scene.width, scene.height), (320, 240));
        assert!(Animator::new(scene, panel_params()).is_ok());
    }
}
