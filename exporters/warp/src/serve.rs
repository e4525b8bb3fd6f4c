//! `frond-warp serve`: the live animation on a web page.
//!
//! Three threads: the simulation (fixed 30 Hz steps on absolute deadlines, publishing each frame
//! into a shared slot), the pose listener (subscribes to `frondd` through `frond_sdk`, reconnects,
//! and reports the connection state), and the HTTP server (`frond_web`'s, as the console's:
//! the same access rules, admission and bounds) serving:
//!
//! - `GET /` the page (canvas, controls, daemon state, frames per second);
//! - `GET /frame` the latest frame as raw RGBA (`X-Width`, `X-Height`, `X-Frame` headers;
//!   `?have=N` answers 204, no body, while frame `N` is still the latest);
//! - `GET /still` the unwarped composite, raw RGBA (what a still frame looks like);
//! - `GET /status` JSON: frame number, simulation fps, daemon state, wind source, parameters;
//! - `POST /params` JSON controls (`direction_deg`, `strength`, `interval_s`, `gamma`, `c`,
//!   `rigidity`, `cell`, `lambda`, `grid`), validated; applied at the next frame. A bad value
//!   answers 400 with every problem named.
//!
//! When the daemon streams poses, the root joint drives direction, strength and interval (the
//! page says "hand"; with `frond sim start` the daemon's element 0 is the simulated plant, so its
//! bend under the simulation's wind drives the picture); otherwise, with `--wind-sim SPEC`, seed
//! 003's simulation wind blows (the page says "simulation"), else the procedural wind uses the
//! page's settings (and says so).
//!
//! Who may use the page is the console's rule ([`frond_web::access`]): on a loopback address,
//! requests that name it by a loopback literal and come from its own page; elsewhere, the token
//! printed in the URL (or `--token-file`).

use std::net::TcpListener;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use frond_protocol::printable;
use frond_web::access::{self, Access};
use frond_web::gate::Limits;
use frond_web::http::{HeaderValue, Request, Response};
use frond_web::server::{Routes, Server};
use serde::{Deserialize, Serialize};

use crate::compose::Animator;
use crate::params::{InvalidParams, SceneParams};
use crate::wind::{HandWind, SimWind};

/// Simulation rate of the live preview.
pub const SERVE_FPS: f32 = 30.0;

/// Controls the page can change (all optional; missing ones keep their value).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Controls {
    /// Wind direction, degrees (0 = right, 90 = down).
    pub direction_deg: Option<f32>,
    /// Wind strength [0, 1].
    pub strength: Option<f32>,
    /// Interval between injections, seconds.
    pub interval_s: Option<f32>,
    /// Damping gamma of every layer.
    pub gamma: Option<f32>,
    /// Wave speed c of every layer.
    pub c: Option<f32>,
    /// Rigidity r of every layer.
    pub rigidity: Option<f32>,
    /// Cell size (s_x = s_y) of every layer, pixels.
    pub cell: Option<u32>,
    /// Scale factor (lambda_x; lambda_y keeps its ratio) of every layer.
    pub lambda: Option<f32>,
    /// Wind grid cells per side.
    pub grid: Option<u32>,
}

impl Controls {
    /// Applies to a copy of `params` and validates the result.
    pub fn apply(&self, params: &SceneParams) -> Result<SceneParams, InvalidParams> {
        let mut p = params.clone();
        if let Some(v) = self.direction_deg {
            p.wind.direction_deg = v;
        }
        if let Some(v) = self.strength {
            p.wind.strength = v;
        }
        if let Some(v) = self.interval_s {
            p.wind.interval_s = v;
        }
        if let Some(v) = self.grid {
            p.fluid.grid = v;
        }
        for l in &mut p.layers {
            if let Some(v) = self.gamma {
                l.gamma = v;
            }
            if let Some(v) = self.c {
                l.c = v;
            }
            if let Some(v) = self.rigidity {
                l.rigidity = v;
            }
            if let Some(v) = self.cell {
                l.cell_x = v;
                l.cell_y = v;
            }
            if let Some(v) = self.lambda {
                let ratio = if l.lambda_x > 0.0 { l.lambda_y / l.lambda_x } else { 1.0 / 3.0 };
                l.lambda_x = v;
                l.lambda_y = v * ratio;
            }
        }
        p.validate()?;
        Ok(p)
    }
}

/// Connection state to the daemon, as shown on the page.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DaemonState {
    /// Connected and receiving poses.
    pub connected: bool,
    /// Human-readable state.
    pub message: String,
}

struct Shared {
    frame: Vec<u8>,
    frame_no: u64,
    fps: f32,
    params: SceneParams,
    pending: Option<SceneParams>,
    daemon: DaemonState,
    /// Latest root joint from the daemon and when it arrived.
    root: Option<([f32; 3], Instant)>,
    /// `hand`, `simulation` or `procedural`.
    wind_source: &'static str,
}

/// Options of [`serve`].
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Address to listen on (`127.0.0.1:0` picks a free port).
    pub listen: String,
    /// Where the poses come from: the daemon's socket directory, or a `frond-zenoh` bridge.
    pub source: frond_sdk::Source,
    /// Do not try to reach the daemon at all.
    pub no_daemon: bool,
    /// Seed 003's simulation wind for when no hand drives the wind (`--wind-sim`).
    pub sim_wind: Option<SimWind>,
    /// The token's file (`--token-file`); without it a page beyond loopback gets a fresh token.
    pub token_file: Option<PathBuf>,
}

/// Runs the preview until the process ends. Prints `listening on http://ADDR/` once bound.
pub fn serve(animator: Animator, opts: ServeOptions) -> anyhow::Result<()> {
    let bound = bind(&opts.listen, opts.token_file.as_deref())?;
    let shared = Arc::new(Mutex::new(Shared {
        frame: animator.frame().to_vec(),
        frame_no: 0,
        fps: 0.0,
        params: animator.params().clone(),
        pending: None,
        daemon: DaemonState { connected: false, message: "not connected yet".into() },
        root: None,
        wind_source: "procedural",
    }));
    let (w, h) = (animator.scene().width, animator.scene().height);
    let still = animator.scene().still();
    let stop = Arc::new(AtomicBool::new(false));
    let sim_wind = opts.sim_wind.clone();
    {
        let shared = shared.clone();
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("warp-sim".into())
            .spawn(move || sim_loop(animator, sim_wind, shared, stop))?;
    }
    if opts.no_daemon {
        shared.lock().expect("lock").daemon.message = "daemon disabled (--no-daemon): procedural wind".into();
    } else {
        let shared = shared.clone();
        let source = opts.source.clone();
        std::thread::Builder::new().name("warp-poses".into()).spawn(move || pose_loop(source, shared))?;
    }
    let site = Routes(move |req: &Request| match (req.method.as_str(), req.path.as_str()) {
        ("GET" | "HEAD", "/") => text(200, PAGE, "text/html; charset=utf-8"),
        ("GET" | "HEAD", "/frame") => {
            let s = shared.lock().expect("lock");
            latest_frame(req, &s.frame, w, h, s.frame_no)
        }
        ("GET" | "HEAD", "/still") => Response::new(200, "application/octet-stream", still.clone()),
        ("GET" | "HEAD", "/status") => {
            let s = shared.lock().expect("lock");
            let body = serde_json::json!({
                "frame": s.frame_no,
                "fps": s.fps,
                "width": w,
                "height": h,
                "daemon": s.daemon,
                "wind_source": s.wind_source,
                "params": s.params,
            });
            text(200, &body.to_string(), "application/json")
        }
        ("POST", "/params") => {
            match body_text(req)
                .and_then(|body| serde_json::from_str::<Controls>(body).map_err(BadBody::Controls))
            {
                Err(e) => text(400, &e.to_string(), "text/plain; charset=utf-8"),
                Ok(ctl) => {
                    let mut s = shared.lock().expect("lock");
                    let base = s.pending.clone().unwrap_or_else(|| s.params.clone());
                    match ctl.apply(&base) {
                        Ok(p) => {
                            s.pending = Some(p);
                            text(200, "ok", "text/plain")
                        }
                        Err(e) => text(400, &e.to_string(), "text/plain; charset=utf-8"),
                    }
                }
            }
        }
        _ => text(404, "not found", "text/plain"),
    });
    bound.run(&format!("a {w}x{h} preview"), site, Limits::default())?;
    stop.store(true, Ordering::Relaxed);
    Ok(())
}

/// A preview's listening socket and who may use it.
pub(crate) struct Bound {
    listener: TcpListener,
    access: Access,
    /// `ADDR` of `http://ADDR/`.
    addr: String,
}

/// Listens on `listen` (a port 0 picks a free one). Beyond loopback every request needs the
/// token: `--token-file`'s, else a fresh one, printed in the URL.
pub(crate) fn bind(listen: &str, token_file: Option<&std::path::Path>) -> anyhow::Result<Bound> {
    let listener =
        TcpListener::bind(listen).map_err(|e| anyhow::anyhow!("cannot listen on {listen}: {e}"))?;
    let local = listener.local_addr()?;
    let loopback = local.ip().is_loopback();
    let token = match token_file {
        Some(path) => Some(access::read_token_file(path).map_err(|e| anyhow::anyhow!("--token-file {e}"))?),
        None if loopback => None,
        None => Some(access::new_token()),
    };
    Ok(Bound { access: Access { loopback, port: local.port(), token }, addr: local.to_string(), listener })
}

impl Bound {
    /// Prints `listening on http://ADDR/` (the line scripts and tests wait for; with
    /// `?token=T` when a fresh token is needed), says what is served on stderr, and serves
    /// `site` until the process ends.
    pub(crate) fn run(
        self,
        what: &str,
        site: impl frond_web::server::Site,
        limits: Limits,
    ) -> Result<(), frond_binmain::StdoutError> {
        let addr = &self.addr;
        let query = match (&self.access.token, self.access.loopback) {
            (Some(t), false) => format!("?token={t}"),
            _ => String::new(),
        };
        frond_binmain::outln!("listening on http://{addr}/{query}")?;
        frond_binmain::errln!("frond-warp: serving {what} on http://{addr}/");
        use std::io::Write;
        std::io::stdout().flush().map_err(frond_binmain::StdoutError)?;
        Server::new(self.access, limits, Arc::new(site)).serve(self.listener);
        Ok(())
    }
}

/// Why a `POST` body was refused (answered 400 with this text).
#[derive(Debug, thiserror::Error)]
pub(crate) enum BadBody {
    /// The bytes are not UTF-8.
    #[error("request body is not UTF-8")]
    NotUtf8,
    /// `/params`: not the page's controls.
    #[error("bad controls JSON: {0}")]
    Controls(serde_json::Error),
    /// `/sketch` (the cage mode): not a sketch of the picture.
    #[error("sketch: {0}")]
    Sketch(frond_cage::sketch::SketchError),
}

/// The request's body as UTF-8 text (its size is bounded by the server's limits).
pub(crate) fn body_text(req: &Request) -> Result<&str, BadBody> {
    std::str::from_utf8(&req.body).map_err(|_| BadBody::NotUtf8)
}

/// `GET /frame[?have=N]`: frame `frame_no` as [`raw_frame`], or 204 (no body) when the client
/// says it has it already.
pub(crate) fn latest_frame(req: &Request, rgba: &[u8], w: usize, h: usize, frame_no: u64) -> Response {
    if have_frame(req) == Some(frame_no) {
        text(204, "", "text/plain")
    } else {
        raw_frame(rgba.to_vec(), w, h, frame_no)
    }
}

/// `N` of a `?have=N` query.
fn have_frame(req: &Request) -> Option<u64> {
    req.param("have")?.parse().ok()
}

/// A raw RGBA frame with its size and number in `X-Width`, `X-Height`, `X-Frame`.
pub(crate) fn raw_frame(rgba: Vec<u8>, w: usize, h: usize, frame_no: u64) -> Response {
    Response::new(200, "application/octet-stream", rgba)
        .with("X-Width", HeaderValue::number(w as u64))
        .with("X-Height", HeaderValue::number(h as u64))
        .with("X-Frame", HeaderValue::number(frame_no))
}

/// A text answer.
pub(crate) fn text(code: u16, body: &str, ctype: &'static str) -> Response {
    Response::new(code, ctype, body)
}

fn sim_loop(
    mut animator: Animator,
    sim_wind: Option<SimWind>,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
) {
    let dt = 1.0 / SERVE_FPS;
    let period = Duration::from_secs_f32(dt);
    let mut next = Instant::now();
    let mut hand = HandWind::new();
    let start = Instant::now();
    let mut window_start = Instant::now();
    let mut window_frames = 0u32;
    let mut fps = 0.0f32;
    let mut spare = animator.frame().to_vec();
    while !stop.load(Ordering::Relaxed) {
        let (pending, root) = {
            let mut s = shared.lock().expect("lock");
            (s.pending.take(), s.root)
        };
        if let Some(p) = pending {
            // Validated by the HTTP handler; a failure here would only repeat its message.
            let _ = animator.set_params(p);
        }
        // Hand-driven while poses are fresh.
        let live = root.filter(|(_, at)| at.elapsed() < Duration::from_millis(500));
        if let Some((root_deg, _)) = live {
            animator.set_procedural(false);
            let mut wind = animator.params().wind;
            hand.update(start.elapsed().as_secs_f64(), root_deg, &mut wind);
            let _ = animator.set_wind(wind);
        } else if let Some(sim) = &sim_wind {
            animator.set_procedural(false);
            let mut wind = animator.params().wind;
            sim.update(start.elapsed().as_secs_f64(), &mut wind);
            let _ = animator.set_wind(wind);
        } else {
            animator.set_procedural(true);
        }
        animator.step(dt);
        spare.copy_from_slice(animator.frame());
        window_frames += 1;
        let el = window_start.elapsed().as_secs_f32();
        if el >= 1.0 {
            fps = window_frames as f32 / el;
            window_frames = 0;
            window_start = Instant::now();
        }
        {
            let mut s = shared.lock().expect("lock");
            std::mem::swap(&mut s.frame, &mut spare);
            s.frame_no += 1;
            s.fps = fps;
            s.params = animator.params().clone();
            s.wind_source = match (live.is_some(), sim_wind.is_some()) {
                (true, _) => "hand",
                (false, true) => "simulation",
                (false, false) => "procedural",
            };
        }
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now; // overran: do not try to catch up
        }
    }
}

fn pose_loop(source: frond_sdk::Source, shared: Arc<Mutex<Shared>>) {
    follow_daemon(&source, "procedural wind", |event| {
        let mut s = shared.lock().expect("lock");
        match event {
            DaemonEvent::State(state) => s.daemon = state,
            DaemonEvent::Rig(_) => {}
            DaemonEvent::Pose(p) => {
                if p.element.is_global() {
                    s.root = Some((p.joints_deg[0], Instant::now()));
                }
            }
        }
    })
}

/// What [`follow_daemon`] reports.
pub(crate) enum DaemonEvent<'a> {
    /// The connection state changed.
    State(DaemonState),
    /// The daemon's rig (at connection and whenever it changes).
    Rig(&'a str),
    /// A pose arrived.
    Pose(&'a frond_sdk::Pose),
}

/// Subscribes to the daemon at `source` for ever (reconnecting, retrying every 2 s while it is
/// absent) and reports its state, rig and poses to `on`. `fallback` says what the page shows
/// while there are no poses (e.g. "procedural wind").
pub(crate) fn follow_daemon(
    source: &frond_sdk::Source,
    fallback: &str,
    mut on: impl FnMut(DaemonEvent<'_>),
) -> ! {
    fn set(on: &mut dyn FnMut(DaemonEvent<'_>), connected: bool, message: String) {
        on(DaemonEvent::State(DaemonState { connected, message }))
    }
    loop {
        let opts = frond_sdk::Subscriber::options()
            .reconnect(true)
            .give_up_after(None)
            .read_timeout(Some(Duration::from_millis(500)));
        match opts.subscribe(source) {
            Err(e) => {
                set(&mut on, false, format!("no daemon at {source}: {fallback} ({e})"));
                std::thread::sleep(Duration::from_secs(2));
            }
            Ok(mut sub) => {
                let rig = sub.hello().rig_name.clone();
                set(&mut on, true, format!("connected to {source} (rig {})", printable(&rig)));
                on(DaemonEvent::Rig(&rig));
                loop {
                    match sub.next_event() {
                        Ok(frond_sdk::Event::Pose(p)) => on(DaemonEvent::Pose(&p)),
                        Ok(frond_sdk::Event::Disconnected) => set(
                            &mut on,
                            false,
                            format!("daemon at {source} went away; reconnecting ({fallback})"),
                        ),
                        Ok(frond_sdk::Event::Reconnected(h)) | Ok(frond_sdk::Event::RigChanged(h)) => {
                            let rig = printable(&h.rig_name);
                            set(&mut on, true, format!("connected to {source} (rig {rig})"));
                            on(DaemonEvent::Rig(&h.rig_name));
                        }
                        Ok(_) => {}
                        Err(frond_sdk::SdkError::Timeout { .. }) => {}
                        Err(e) => {
                            set(&mut on, false, format!("daemon stream ended: {e}; retrying ({fallback})"));
                            std::thread::sleep(Duration::from_secs(2));
                            break;
                        }
                    }
                }
            }
        }
    }
}

const PAGE: &str = include_str!("page.html");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_have_query_is_read_and_anything_else_ignored() {
        let have_frame = |target: &str| {
            let (path, query) = frond_web::http::split_target(target);
            have_frame(&Request { path, query, ..Request::default() })
        };
        assert_eq!(have_frame("/frame?have=12"), Some(12));
        assert_eq!(have_frame("/frame?x=1&have=7"), Some(7));
        assert_eq!(have_frame("/frame"), None);
        assert_eq!(have_frame("/frame?have=-1"), None);
        assert_eq!(have_frame("/frame?have=99999999999999999999999"), None);
    }
}
