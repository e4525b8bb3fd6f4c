//! `frond-warp serve --mode cage`: seed 004 live on a web page.
//!
//! The page shows the picture with the layer's multiscale cage tree drawn over it. The user
//! draws a sketch with the pointer (mouse, pen or touch) and watches the layer morph towards it
//! over `--morph-s` seconds (seed 004, section 5: MVC propagation, Eq. 1, adaptation, pruning);
//! a stroke that ends near its start is closed (the new silhouette), any other is an open stroke
//! that reshapes the side it follows. Escape (or the page's Reset) returns to the rest shape.
//! While no sketch is shown and the daemon streams poses, the crown cage is skinned to the plant
//! skeleton (seed 000, Eq. 1; see [`crate::cage_skin`]) and the live hand bends the plant with its
//! shape kept.
//!
//! Three threads: the morph (fixed 30 Hz steps on absolute deadlines; a frame is only computed
//! when its input changed), the pose listener (`serve::follow_daemon`) and the HTTP
//! server:
//!
//! - `GET /` the page;
//! - `GET /frame` the latest frame as raw RGBA (`X-Width`, `X-Height`, `X-Frame` headers;
//!   `?have=N` answers 204, no body, while frame `N` is still the latest);
//! - `GET /still` the picture at rest, raw RGBA;
//! - `GET /cages` the current cages, JSON `{"size":[w,h],"crown":ID,"cages":[{"id":..,
//!   "parent":..|null,"kind":"internal"|"leaf","pruned":bool,"vertices":[[x,y],...]}]}`;
//! - `GET /status` JSON: frame, fps, `drive` (`rest`, `hand` or `sketch`), the morph's `t`, the
//!   final frame's Frechet distance to the sketch (`frechet_px`, section 6.2), daemon state, rig;
//! - `POST /sketch` a `sketch.json` body (as `frond-warp morph --sketch` reads), validated; a bad
//!   one answers 400 naming the problem;
//! - `POST /reset` back to the rest shape (and the hand).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use frond_cage::morph::{MorphOptions, MorphPlan};
use frond_cage::sketch::Sketch;
use frond_cage::{CageKind, CageTree, Point};
use frond_motion::skeleton::Skeleton;
use frond_web::gate::Limits;
use frond_web::http::Request;
use frond_web::server::Routes;

use crate::Scene;
use crate::cage_skin::CageSkin;
use crate::morph::MAX_SKETCH_FILE_BYTES;
use crate::morph_frames::MorphFrames;
use crate::serve::{
    BadBody, DaemonEvent, DaemonState, bind, body_text, follow_daemon, latest_frame, raw_frame, text,
};

/// Frame rate of the cage preview.
pub const CAGE_SERVE_FPS: f64 = 30.0;
/// Poses older than this no longer drive the plant.
const POSE_FRESH: Duration = Duration::from_millis(500);

/// Options of [`serve_cage`].
#[derive(Debug, Clone)]
pub struct CageServeOptions {
    /// Address to listen on (`127.0.0.1:0` picks a free port).
    pub listen: String,
    /// Daemon socket directory.
    pub source: frond_sdk::Source,
    /// Do not try to reach the daemon at all.
    pub no_daemon: bool,
    /// Where the skeleton stands (default: the bottom centre of the crown).
    pub anchor: Option<Point>,
    /// The skeleton's rig, fixed (`--rig`); otherwise the daemon's rig, loaded by name.
    pub rig: Option<(String, Skeleton)>,
    /// How long a morph towards a sketch plays, seconds.
    pub morph_s: f64,
    /// Adaptation and pruning of sketched morphs.
    pub opts: MorphOptions,
    /// The token's file (`--token-file`); without it a page beyond loopback gets a fresh token.
    pub token_file: Option<std::path::PathBuf>,
}

/// What drives the picture now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Drive {
    Rest,
    Hand,
    Sketch,
}

impl Drive {
    fn name(self) -> &'static str {
        match self {
            Drive::Rest => "rest",
            Drive::Hand => "hand",
            Drive::Sketch => "sketch",
        }
    }
}

struct Shared {
    frame: Vec<u8>,
    frame_no: u64,
    fps: f32,
    /// A sketch to morph towards, or `None` to reset; taken by the morph thread.
    request: Option<Option<Sketch>>,
    daemon: DaemonState,
    /// Latest element-0 pose and when it arrived.
    pose: Option<([[f32; 3]; 4], Instant)>,
    /// The skeleton the hand drives, and its rig's name.
    skeleton: Option<(String, Skeleton)>,
    rig_note: String,
    drive: Drive,
    t: f64,
    frechet_px: Option<f64>,
    cages: Vec<Vec<Point>>,
    pruned: Vec<bool>,
}

/// Runs the cage preview of `scene`'s first layer with cage tree `tree` until the process ends.
/// Prints `listening on http://ADDR/` once bound.
pub fn serve_cage(scene: Scene, tree: CageTree, opts: CageServeOptions) -> anyhow::Result<()> {
    let bound = bind(&opts.listen, opts.token_file.as_deref())?;
    let (w, h) = (scene.width, scene.height);
    let still = scene.still();
    let fixed_rig = opts.rig.is_some();
    let shared = Arc::new(Mutex::new(Shared {
        frame: still.clone(),
        frame_no: 0,
        fps: 0.0,
        request: None,
        daemon: DaemonState { connected: false, message: "not connected yet".into() },
        pose: None,
        rig_note: match &opts.rig {
            Some((name, _)) => format!("rig {name} (--rig)"),
            None => "the daemon's rig, once connected".into(),
        },
        skeleton: opts.rig.clone(),
        drive: Drive::Rest,
        t: 0.0,
        frechet_px: None,
        cages: tree.cages.iter().map(|c| c.vertices.clone()).collect(),
        pruned: vec![false; tree.cages.len()],
    }));
    let stop = Arc::new(AtomicBool::new(false));
    {
        let (shared, stop, tree, opts) = (shared.clone(), stop.clone(), tree.clone(), opts.clone());
        std::thread::Builder::new()
            .name("warp-morph".into())
            .spawn(move || morph_loop(&scene, &tree, &opts, &shared, &stop))?;
    }
    if opts.no_daemon {
        shared.lock().expect("lock").daemon.message = "daemon disabled (--no-daemon): sketch only".into();
    } else {
        let (shared, source) = (shared.clone(), opts.source.clone());
        std::thread::Builder::new()
            .name("warp-poses".into())
            .spawn(move || follow_daemon(&source, "sketch only", |e| on_daemon(&shared, fixed_rig, e)))?;
    }
    let crown_id = tree.cages[frond_cage::morph::largest_root(&tree)].id;
    let morph_s = opts.morph_s;
    let site = Routes(move |req: &Request| match (req.method.as_str(), req.path.as_str()) {
        ("GET" | "HEAD", "/") => text(200, PAGE, "text/html; charset=utf-8"),
        ("GET" | "HEAD", "/frame") => {
            let s = shared.lock().expect("lock");
            latest_frame(req, &s.frame, w, h, s.frame_no)
        }
        ("GET" | "HEAD", "/still") => raw_frame(still.clone(), w, h, 0),
        ("GET" | "HEAD", "/cages") => {
            let (cages, pruned) = {
                let s = shared.lock().expect("lock");
                (s.cages.clone(), s.pruned.clone())
            };
            text(200, &cages_json(&tree, crown_id, &cages, &pruned), "application/json")
        }
        ("GET" | "HEAD", "/status") => {
            let s = shared.lock().expect("lock");
            let body = serde_json::json!({
                "mode": "cage",
                "frame": s.frame_no,
                "fps": s.fps,
                "width": w,
                "height": h,
                "drive": s.drive.name(),
                "t": s.t,
                "frechet_px": s.frechet_px,
                "daemon": s.daemon,
                "rig": s.rig_note,
                "morph_s": morph_s,
            });
            text(200, &body.to_string(), "application/json")
        }
        ("POST", "/sketch") => match body_text(req)
            .and_then(|body| Sketch::from_json(body, tree.size).map_err(BadBody::Sketch))
        {
            Ok(sketch) => {
                shared.lock().expect("lock").request = Some(Some(sketch));
                text(200, "ok", "text/plain")
            }
            Err(e) => text(400, &e.to_string(), "text/plain; charset=utf-8"),
        },
        ("POST", "/reset") => {
            shared.lock().expect("lock").request = Some(None);
            text(200, "ok", "text/plain")
        }
        _ => text(404, "not found", "text/plain"),
    });
    // A sketch may be as large as a sketch file.
    let limits = Limits { max_body_bytes: MAX_SKETCH_FILE_BYTES as usize, ..Limits::default() };
    bound.run(&format!("a {w}x{h} cage preview"), site, limits)?;
    stop.store(true, Ordering::Relaxed);
    Ok(())
}

/// The pose listener's events into the shared state: the daemon's rig is loaded by name (unless
/// `--rig` fixed it) so the skeleton matches the poses.
fn on_daemon(shared: &Mutex<Shared>, fixed_rig: bool, event: DaemonEvent<'_>) {
    match event {
        DaemonEvent::State(state) => shared.lock().expect("lock").daemon = state,
        DaemonEvent::Rig(name) if !fixed_rig => {
            // An embedded rig only: a name a peer sends is never opened as a path.
            let loaded = frond_formats::rig_files::recorded_rig(name);
            let mut s = shared.lock().expect("lock");
            match loaded {
                Ok(rig) => {
                    s.skeleton = Some((name.to_string(), Skeleton::from_rig(&rig.rig)));
                    s.rig_note = format!("rig {name} (the daemon's)");
                }
                Err(e) => {
                    s.skeleton = None;
                    s.rig_note = format!("the daemon's {e}");
                }
            }
        }
        DaemonEvent::Rig(_) => {}
        DaemonEvent::Pose(p) => {
            if p.element.is_global() {
                shared.lock().expect("lock").pose = Some((p.joints_deg, Instant::now()));
            }
        }
    }
}

/// Plans each request (a sketch, or the skeleton-driven rest plan) and renders its frames.
fn morph_loop(
    scene: &Scene,
    tree: &CageTree,
    opts: &CageServeOptions,
    shared: &Mutex<Shared>,
    stop: &AtomicBool,
) {
    let period = Duration::from_secs_f64(1.0 / CAGE_SERVE_FPS);
    let mut request: Option<Sketch> = None;
    let mut frame = Vec::with_capacity(scene.width * scene.height * 4);
    let mut warped = Vec::new();
    let mut fps = FpsWindow::new();
    while !stop.load(Ordering::Relaxed) {
        let plan = match &request {
            Some(sketch) => MorphPlan::new(tree.clone(), sketch, opts.opts),
            None => MorphPlan::driven(tree.clone(), MorphOptions { adapt: opts.opts.adapt, prune: false }),
        };
        let mut frames = MorphFrames::new(scene, &plan);
        let started = Instant::now();
        let mut skin: Option<(Skeleton, CageSkin)> = None;
        // What the last computed frame showed: a frame is only computed when this changes.
        let mut shown: Option<FrameKey> = None;
        let mut next = Instant::now();
        {
            let mut s = shared.lock().expect("lock");
            s.pruned = plan.pruned().to_vec();
            s.frechet_px = None;
        }
        loop {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            let (req, pose, skeleton) = {
                let mut s = shared.lock().expect("lock");
                (s.request.take(), s.pose, s.skeleton.clone())
            };
            if let Some(r) = req {
                request = r;
                break;
            }
            let (drive, t, joints) = if request.is_some() {
                (Drive::Sketch, (started.elapsed().as_secs_f64() / opts.morph_s).min(1.0), None)
            } else {
                match (pose.filter(|(_, at)| at.elapsed() < POSE_FRESH), skeleton) {
                    (Some((joints, _)), Some((_, sk))) => (Drive::Hand, 0.0, Some((joints, sk))),
                    _ => (Drive::Rest, 0.0, None),
                }
            };
            let key = (drive, t, joints.map(|(j, _)| j));
            if shown != Some(key) {
                match (drive, joints) {
                    (Drive::Sketch, _) => frames.update_cages(t),
                    (Drive::Hand, Some((j, sk))) => {
                        if skin.as_ref().is_none_or(|(have, _)| *have != sk) {
                            skin = Some((sk, CageSkin::new(plan.tree(), plan.crown(), sk, opts.anchor)));
                        }
                        let crown = skin.as_ref().expect("just set").1.crown_at(&j);
                        frames.set_crown(&crown);
                    }
                    _ => frames.update_cages(0.0),
                }
                frames.compose(t, &mut frame);
                let frechet =
                    (drive == Drive::Sketch && t >= 1.0).then(|| frames.outline_distance(1.0, &mut warped));
                fps.tick();
                let mut s = shared.lock().expect("lock");
                std::mem::swap(&mut s.frame, &mut frame);
                s.frame_no += 1;
                s.cages.clone_from_slice(frames.cages());
                s.drive = drive;
                s.t = t;
                if frechet.is_some() {
                    s.frechet_px = frechet;
                }
                shown = Some(key);
            }
            shared.lock().expect("lock").fps = fps.rate();
            next += period;
            let now = Instant::now();
            if next > now {
                std::thread::sleep(next - now);
            } else {
                next = now; // overran: do not try to catch up
            }
        }
    }
}

/// What a frame shows: its drive, the morph's `t` and the pose that bent it.
type FrameKey = (Drive, f64, Option<[[f32; 3]; 4]>);

/// Frames computed per second over the last second.
struct FpsWindow {
    start: Instant,
    frames: u32,
    rate: f32,
}

impl FpsWindow {
    fn new() -> FpsWindow {
        FpsWindow { start: Instant::now(), frames: 0, rate: 0.0 }
    }

    fn tick(&mut self) {
        self.frames += 1;
    }

    fn rate(&mut self) -> f32 {
        let el = self.start.elapsed().as_secs_f32();
        if el >= 1.0 {
            self.rate = self.frames as f32 / el;
            self.frames = 0;
            self.start = Instant::now();
        }
        self.rate
    }
}

/// `GET /cages`: the tree's structure with the current vertices.
fn cages_json(tree: &CageTree, crown: u32, now: &[Vec<Point>], pruned: &[bool]) -> String {
    let round = |p: &Point| [(p[0] * 100.0).round() / 100.0, (p[1] * 100.0).round() / 100.0];
    let cages: Vec<serde_json::Value> = tree
        .cages
        .iter()
        .enumerate()
        .map(|(i, c)| {
            serde_json::json!({
                "id": c.id,
                "parent": c.parent.map(|p| tree.cages[p].id),
                "kind": match c.kind { CageKind::Internal => "internal", CageKind::Leaf => "leaf" },
                "pruned": pruned.get(i).copied().unwrap_or(false),
                "vertices": now.get(i).unwrap_or(&c.vertices).iter().map(round).collect::<Vec<_>>(),
            })
        })
        .collect();
    serde_json::json!({ "size": tree.size, "crown": crown, "cages": cages }).to_string()
}

const PAGE: &str = include_str!("cage_page.html");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cages_json_carries_the_structure_and_the_current_vertices() {
        let crown = vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        let lobe = vec![[1.0, 1.0], [4.0, 1.0], [4.0, 4.0]];
        let tree = CageTree::from_parts(
            [20, 20],
            [(5, None, CageKind::Internal, crown.clone()), (9, Some(5), CageKind::Leaf, lobe.clone())],
        )
        .unwrap();
        let moved = vec![crown.iter().map(|p| [p[0] + 0.125, p[1]]).collect(), lobe];
        let v: serde_json::Value =
            serde_json::from_str(&cages_json(&tree, 5, &moved, &[false, true])).unwrap();
        assert_eq!(v["size"], serde_json::json!([20, 20]));
        assert_eq!(v["crown"], 5);
        assert_eq!(v["cages"][0]["parent"], serde_json::Value::Null);
        assert_eq!(v["cages"][1]["parent"], 5);
        assert_eq!(v["cages"][1]["kind"], "leaf");
        assert_eq!(v["cages"][1]["pruned"], true);
        assert_eq!(v["cages"][0]["vertices"][1], serde_json::json!([10.13, 0.0]));
    }
}
