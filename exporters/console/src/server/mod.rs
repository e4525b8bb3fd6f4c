//! The console's endpoints (the pose and warp WebSockets in `sockets`), a [`Site`] of
//! `frond_web`'s server: it admits connections (no slow client locks the operator out), reads
//! each request within its deadline and checks it against the access policy before the console
//! sees it. Each page's pose WebSocket has a thread that sends the latest poses at the display
//! rate.
//!
//! Endpoints (all behind [`crate::access`]):
//! - `GET /` the page; `/console.js` (with `/calibrate.js`, its guided calibration), `/console.css`;
//!   three.js under `/vendor/`;
//! - `GET /rig.glb` the daemon's rig baked by frond-gltf at rest, `GET /api/scene` its node map;
//!   `GET /api/rigs/NAME.glb` and `/api/rigs/NAME.json` the same of any rig a field may be
//!   drawn with (an embedded rig, or `--rig`'s), by name (`fields`);
//! - `GET /api/hello` the stream's hello and element table, `GET /api/status` the daemon's status
//!   (as `frond status --json` has it) with the console's own counters;
//! - `GET /api/camera`, `/api/camera/webcam-N.jpg`, `/camera.js` the camera panel (`camera`);
//! - `GET /api/takes` the takes (as `frond take list --json`), `GET /api/takes/NAME/play` a take's
//!   main skeleton at 60 FPS for the view, `/api/takes/NAME.glb` and `.jsonl` as downloads;
//! - `POST /api/...`: control actions ([`crate::actions`]: recording, markers, playback, rig,
//!   filter, calibration, field keys, guided motion), sent on the control socket with the
//!   console's own credentials (the daemon's allow-list decides);
//! - `GET /api/rigs` the embedded rigs the page offers;
//! - `GET /api/calibrate`, `POST /api/calibrate/{start,step,apply,cancel}` the guided
//!   calibration ([`crate::calibrate`]);
//! - `GET /ws/warp` the seed-001 warp preview's WebSocket ([`crate::warp_panel`]): binary JPEG
//!   frames at 30 Hz and `{"type":"warp","state":{...}}` twice a second;
//! - `GET /ws` the pose WebSocket: JSON text messages, `{"type":"hello",...}` when the rig, the
//!   element table or the connection changes, and `{"type":"poses","poses":[...]}` at most at the
//!   display rate with each element's latest pose that the page does not have yet; a running
//!   field's table (`{"type":"fields",...}`) when it changes and every field frame once
//!   (`{"type":"field-frames","frames":[...]}`), which the page evaluates ([`crate::meadow`]);
//! - `GET /meadow.js` (with `/meadow_rig.js`), `/field.js` the field's drawing and evaluation, `GET /api/fields/ID/layout`
//!   a running field's plants as bytes ([`crate::meadow::layout_bytes`]).
//!
//! The actions take `POST` alone, the rest `GET` and `HEAD` (the head of GET's answer); another
//! method is answered 405 with `Allow` naming the path's methods, a path not served 404.

use std::collections::HashMap;
use std::io;
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use frond_protocol::{ControlReply, ControlRequest};
use frond_sdk::Hello;
use serde_json::{Value, json};

mod camera;
mod fields;
mod sockets;

use frond_web::access::{Access, Grant, Refusal};
use frond_web::gate::{Gate, Limits};
use frond_web::http::{HeaderValue, Request, Response, attachment};
use frond_web::server::{Server, Site};
use frond_web::work::WorkLimit;

use crate::actions;
use crate::calibrate::Calibrations;
use crate::daemon_link::DaemonLink;
use crate::relay::{Live, latency_json_of};
use crate::scene::{self, RigScene};
use crate::takes;
use crate::warp_panel::{self, WarpPanel};

/// Most pose WebSockets at once; a page past them closes the oldest (so that pages that never
/// go, or never read, cannot keep a new one out).
pub const MAX_SOCKETS: usize = 16;
/// Heavy requests answered at once (a take baked, scanned or resampled); more wait
/// 5 s, then are answered 503.
pub const MAX_HEAVY: usize = 2;
/// How long a heavy request waits for its turn.
const HEAVY_WAIT: Duration = Duration::from_secs(5);
/// Most bytes queued for a slow page before its frames are dropped (the latest still follows).
const MAX_QUEUED_BYTES: usize = 256 * 1024;

/// What the server was asked.
#[derive(Debug, Clone)]
pub struct Config {
    /// The daemon's socket directory.
    pub socket_dir: PathBuf,
    /// The takes directory (the daemon's, for the takes panel).
    pub takes_dir: PathBuf,
    /// Who may use the console.
    pub access: Access,
    /// A rig to show instead of the daemon's (`--rig`), loaded and baked before the console
    /// starts ([`scene::load`]), so that a rig it cannot show is refused at once.
    pub rig: Option<Arc<RigScene>>,
    /// Pose messages per second to each page.
    pub display_hz: u32,
    /// Run the seed-001 warp preview panel (`--no-warp` turns it off).
    pub warp: bool,
}

/// Counters of the console itself.
#[derive(Debug, Default)]
struct Counters {
    sockets: AtomicUsize,
    /// Open pages' sockets (oldest first), to close the oldest for a new one.
    pages: Mutex<sockets::Pages>,
    /// Pages closed to make room for a newer one.
    pages_closed: AtomicU64,
    messages: AtomicU64,
    poses_sent: AtomicU64,
    dropped: AtomicU64,
    refused: AtomicU64,
}

/// Why the view has no rig to show (answered 503).
#[derive(Debug, Clone, thiserror::Error)]
enum NoScene {
    /// No `--rig` and no daemon's hello yet.
    #[error("the daemon is not connected yet: its rig is not known")]
    NotConnected,
    /// The daemon's rig came from a file: the operator gives the console that file, as a name
    /// from a peer is never opened as a path.
    #[error(
        "the daemon's rig {name:?} is not an embedded rig ({embedded}): it was loaded \
         from a file; start frond-console with --rig FILE (that rig's file) to show it"
    )]
    FromFile {
        /// The daemon's rig's name.
        name: String,
        /// The embedded rigs' names.
        embedded: String,
    },
    /// The rig could not be loaded or baked (kept, shared, for the next requests).
    #[error(transparent)]
    Load(Arc<scene::SceneError>),
}

/// The running console.
pub struct Console {
    config: Config,
    live: Arc<Live>,
    counters: Counters,
    scenes: Mutex<HashMap<String, Result<Arc<RigScene>, NoScene>>>,
    /// The plants' ground positions of the field this console started, `[x, z]` metres.
    field: Mutex<Option<Value>>,
    /// The warp preview panel, when on.
    warp: Option<Arc<WarpPanel>>,
    /// The guided calibration.
    calibrations: Arc<Calibrations>,
    /// The one control connection that status reads and actions share.
    daemon: DaemonLink,
    /// The index of the takes directory.
    takes: takes::TakeIndex,
    /// Heavy requests at once.
    heavy: WorkLimit,
    /// The server's admission gate, once serving (for status).
    gate: OnceLock<Arc<Gate>>,
}

const INDEX_HTML: &str = include_str!("../../page/index.html");
const CONSOLE_JS: &str = include_str!("../../page/console.js");
const CALIBRATE_JS: &str = include_str!("../../page/calibrate.js");
const CONSOLE_CSS: &str = include_str!("../../page/console.css");

/// The vendored three.js files: (URL path, body).
const VENDOR: [(&str, &str); 6] = [
    ("/vendor/three/three.module.min.js", include_str!("../../vendor/three/three.module.min.js")),
    ("/vendor/three/three.core.min.js", include_str!("../../vendor/three/three.core.min.js")),
    ("/vendor/three/GLTFLoader.js", include_str!("../../vendor/three/GLTFLoader.js")),
    ("/vendor/three/OrbitControls.js", include_str!("../../vendor/three/OrbitControls.js")),
    ("/vendor/utils/BufferGeometryUtils.js", include_str!("../../vendor/three/BufferGeometryUtils.js")),
    ("/vendor/three/SkeletonUtils.js", include_str!("../../vendor/three/SkeletonUtils.js")),
];

impl Console {
    /// A console for `config`, its subscription started.
    pub fn start(config: Config) -> io::Result<Arc<Console>> {
        let live = Live::new();
        live.spawn(config.socket_dir.clone())?;
        let warp = if config.warp {
            let scene = warp_panel::sample_scene().map_err(io::Error::other)?;
            Some(
                WarpPanel::start(Arc::clone(&live), scene, warp_panel::panel_params())
                    .map_err(io::Error::other)?,
            )
        } else {
            None
        };
        Ok(Arc::new(Console {
            live,
            counters: Counters::default(),
            scenes: Mutex::default(),
            field: Mutex::default(),
            warp,
            calibrations: Arc::default(),
            daemon: DaemonLink::new(config.socket_dir.clone()),
            takes: takes::TakeIndex::new(config.takes_dir.clone()),
            heavy: WorkLimit::new(MAX_HEAVY),
            gate: OnceLock::new(),
            config,
        }))
    }

    /// Serves `listener` until the process ends.
    pub fn serve(self: &Arc<Console>, listener: TcpListener) {
        let server =
            Server::new(self.config.access.clone(), Limits::default(), Arc::clone(self) as Arc<dyn Site>);
        let _ = self.gate.set(Arc::clone(server.gate()));
        server.serve(listener);
    }

    /// A heavy request's answer, once its turn comes (503 when none came in time).
    fn heavy(&self, work: impl FnOnce() -> Response) -> Response {
        self.heavy.run(HEAVY_WAIT, work).unwrap_or_else(|busy| Response::error(503, busy.to_string()))
    }

    /// The answer to `req`: 404 for a path that is not served, 405 with the methods it takes
    /// (`Allow`, RFC 9110, section 15.5.6) for another method, else the endpoint's.
    fn route(&self, req: &Request) -> Response {
        let Some(allow) = methods(&req.path) else {
            return Response::error(404, format!("no {} here", req.path));
        };
        if !allow.split(", ").any(|m| m == req.method) {
            return Response::error(
                405,
                format!("{} {} is not served; it takes {allow}", req.method, req.path),
            )
            .with("Allow", HeaderValue::from_static(allow));
        }
        if allow == POST { self.post(req) } else { self.get(req) }
    }

    /// A `GET` (or `HEAD`) of a path [`methods`] lists.
    fn get(&self, req: &Request) -> Response {
        match req.path.as_str() {
            // The server sets the token cookie when the token matched.
            "/" => Response::new(200, "text/html; charset=utf-8", INDEX_HTML),
            "/console.js" => Response::new(200, "text/javascript; charset=utf-8", CONSOLE_JS),
            "/calibrate.js" => Response::new(200, "text/javascript; charset=utf-8", CALIBRATE_JS),
            "/console.css" => Response::new(200, "text/css; charset=utf-8", CONSOLE_CSS),
            "/meadow.js" | "/meadow_rig.js" | "/field.js" => crate::meadow::page_file(&req.path),
            p if p.starts_with("/api/fields/") => {
                crate::meadow::layout_response(p, |id| self.live.lock().fields.layout(id))
            }
            p if p.starts_with("/api/rigs/") => self.rig_file(&p["/api/rigs/".len()..]),
            "/api/hello" => Response::json(200, &self.hello_json()),
            "/api/status" => self.status(),
            "/api/scene" => match self.scene() {
                Ok(s) => Response::json(200, &s.map),
                Err(e) => Response::error(503, e.to_string()),
            },
            "/rig.glb" => match self.scene() {
                Ok(s) => Response::new(200, "model/gltf-binary", s.glb.clone()),
                Err(e) => Response::error(503, e.to_string()),
            },
            "/api/rigs" => Response::json(
                200,
                &json!(frond_formats::rig_files::EMBEDDED_RIGS.iter().map(|(n, _)| *n).collect::<Vec<_>>()),
            ),
            "/api/calibrate" => Response::json(200, &self.calibrations.state()),
            "/api/field" => Response::json(
                200,
                self.field.lock().unwrap_or_else(|e| e.into_inner()).as_ref().unwrap_or(&Value::Null),
            ),
            "/api/takes" => self.heavy(|| Response::json(200, &self.takes.list())),
            // A WebSocket's path without the upgrade (RFC 9110, section 15.5.22).
            "/ws" | "/ws/warp" => {
                Response::error(426, format!("{} is a WebSocket: open it with an upgrade", req.path))
                    .with("Upgrade", HeaderValue::from_static("websocket"))
                    .with("Connection", HeaderValue::from_static("Upgrade, close"))
            }
            p if p.starts_with("/api/takes/") => self.heavy(|| self.take_file(&p["/api/takes/".len()..])),
            p if camera::serves(p) => self.camera(req),
            p => match VENDOR.iter().find(|(path, _)| *path == p) {
                Some((_, body)) => Response::new(200, "text/javascript; charset=utf-8", *body)
                    .with("Cache-Control", HeaderValue::from_static("max-age=3600")),
                None => Response::error(404, format!("no {p} here")),
            },
        }
    }

    /// A `POST` to a path [`methods`] lists.
    fn post(&self, req: &Request) -> Response {
        match req.path.as_str() {
            "/api/field/start" => self.field_start(req),
            "/api/takes/repair" => {
                match json_body(req).map(|b| b.get("take").and_then(Value::as_str).map(str::to_string)) {
                    Ok(Some(take)) => self.heavy(|| match takes::repair(&self.config.takes_dir, &take) {
                        Ok(v) => Response::json(200, &v),
                        Err(e) => Response::error(e.status, e.message),
                    }),
                    Ok(None) => Response::error(400, "repair needs {\"take\": \"...\"}"),
                    Err(r) => r,
                }
            }
            p if CALIBRATE_PATHS.contains(&p) => self.calibrate(req),
            _ => self.control(req),
        }
    }

    /// `/api/takes/NAME/play`, `/api/takes/NAME.glb`, `/api/takes/NAME.jsonl`.
    fn take_file(&self, rest: &str) -> Response {
        let answer = |r: Result<Response, takes::TakeError>| {
            r.unwrap_or_else(|e| Response::error(e.status, e.message))
        };
        if let Some(name) = rest.strip_suffix("/play") {
            answer(takes::playback(&self.config.takes_dir, name).map(|v| Response::json(200, &v)))
        } else if let Some(name) = rest.strip_suffix(".jsonl") {
            answer(
                takes::jsonl(&self.config.takes_dir, name).map(|t| {
                    download(Response::new(200, "application/x-ndjson", t), &format!("{name}.jsonl"))
                }),
            )
        } else if let Some(name) = rest.strip_suffix(".glb") {
            let daemons = self.live.lock().hello.as_ref().map(|h| h.rig_name.clone());
            let own = self.config.rig.as_deref().map(|s| &s.loaded);
            answer(
                takes::glb(&self.config.takes_dir, name, daemons.as_deref(), own)
                    .map(|b| download(Response::new(200, "model/gltf-binary", b), &format!("{name}.glb"))),
            )
        } else {
            Response::error(404, format!("no /api/takes/{rest} here (NAME/play, NAME.glb, NAME.jsonl)"))
        }
    }

    /// The rig to show: `--rig`, else the daemon's (loaded once per name): an embedded rig only,
    /// as the name comes from the daemon and is never opened as a path here.
    fn scene(&self) -> Result<Arc<RigScene>, NoScene> {
        let name = match (&self.config.rig, &self.live.lock().hello) {
            (Some(scene), _) => return Ok(Arc::clone(scene)),
            (None, Some(h)) => h.rig_name.clone(),
            (None, None) => return Err(NoScene::NotConnected),
        };
        let mut cache = self.scenes.lock().unwrap_or_else(|e| e.into_inner());
        cache
            .entry(name.clone())
            .or_insert_with(|| {
                scene::load_recorded(&name).map(Arc::new).map_err(|e| match e {
                    // The daemon's rig came from a file: the operator gives the console that
                    // file, as a name from a peer is never opened as a path.
                    scene::SceneError::Load {
                        reason:
                            frond_gltf::BakeError::Rig(frond_formats::rig_files::RigFileError::NotEmbedded {
                                name,
                                embedded,
                            }),
                        ..
                    } => NoScene::FromFile { name, embedded },
                    e => NoScene::Load(Arc::new(e)),
                })
            })
            .clone()
    }

    fn hello_json(&self) -> Value {
        let s = self.live.lock();
        json!({
            "type": "hello",
            "connected": s.connected,
            "why": s.why,
            "hello": s.hello.as_ref().map(hello_value),
            "frames": s.frames,
            "gaps": s.gaps,
            "missing": s.missing,
        })
    }

    fn status(&self) -> Response {
        // The rings are copied under the lock and summarised (sorted) outside it: the
        // subscription takes the lock for every pose.
        let (mut console, latency, glove) = {
            let s = self.live.lock();
            let console = json!({
                "connected": s.connected,
                "why": s.why,
                "frames": s.frames,
                "gaps": s.gaps,
                "missing": s.missing,
                "sockets": self.counters.sockets.load(Ordering::Relaxed),
                "sockets_closed": self.counters.pages_closed.load(Ordering::Relaxed),
                "messages": self.counters.messages.load(Ordering::Relaxed),
                "poses_sent": self.counters.poses_sent.load(Ordering::Relaxed),
                "dropped": self.counters.dropped.load(Ordering::Relaxed),
                "refused": self.counters.refused.load(Ordering::Relaxed),
                "connections": self.gate.get().map(|g| gate_json(g)),
                "glove_clock_foreign": s.glove_foreign,
            });
            (console, s.latency.values.clone(), s.glove.values.clone())
        };
        console["latency"] = latency_json_of(&latency);
        // `null` when the glove's clock is not the host's (`glove_clock_foreign` counts those).
        console["glove_latency"] = if glove.is_empty() { Value::Null } else { latency_json_of(&glove) };
        match self.daemon.status() {
            Ok(report) => match serde_json::to_value(&report) {
                Ok(v) => {
                    let health: Vec<Value> = frond_sdk::health::problems(&report)
                        .into_iter()
                        .map(|p| json!({ "what": p.what, "fix": p.fix }))
                        .collect();
                    Response::json(200, &json!({ "daemon": v, "health": health, "console": console }))
                }
                Err(e) => Response::error(502, format!("the daemon's status does not encode: {e}")),
            },
            Err(e) => {
                Response::json(200, &json!({ "daemon": null, "error": e.to_string(), "console": console }))
            }
        }
    }

    /// The guided calibration's actions ([`crate::calibrate`]).
    fn calibrate(&self, req: &Request) -> Response {
        let body = match json_body(req) {
            Ok(b) => b,
            Err(r) => return r,
        };
        let c = &self.calibrations;
        let done = match req.path.as_str() {
            "/api/calibrate/start" => c.start(self.config.socket_dir.clone(), &body),
            "/api/calibrate/step" => c.step(),
            "/api/calibrate/cancel" => Ok(c.cancel()),
            "/api/calibrate/apply" => match c.apply_request() {
                Ok(request) => return self.act(&request),
                Err(e) => Err(e),
            },
            p => return Response::error(404, format!("no {p} here (start, step, apply, cancel)")),
        };
        match done {
            Ok(state) => Response::json(200, &state),
            Err(e) => Response::error(e.status(), e.to_string()),
        }
    }

    fn control(&self, req: &Request) -> Response {
        let body = match json_body(req) {
            Ok(b) => b,
            Err(r) => return r,
        };
        let request = match actions::request(&req.path, &body) {
            Ok(r) => r,
            Err(e) => return Response::error(400, e.to_string()),
        };
        match req.path.as_str() {
            "/api/field/key" | "/api/field/stop" => self.to_every_field(request),
            _ => self.act(&request),
        }
    }

    /// Sends one control request; the daemon's answer as the page's.
    fn act(&self, request: &ControlRequest) -> Response {
        match self.daemon.request(request) {
            Ok(ControlReply::Recording(r)) => Response::json(
                200,
                &json!({"ok": true, "recording": {"name": r.name, "path": r.path, "frames": r.frames, "dropped": r.dropped, "active": r.active}}),
            ),
            Ok(_) => Response::json(200, &json!({ "ok": true })),
            Err(e @ frond_sdk::ControlClientError::Refused { .. }) => Response::error(409, e.to_string()),
            Err(e) => Response::error(502, e.to_string()),
        }
    }
}

/// `Allow` of the paths that take `POST` alone.
const POST: &str = "POST";
/// `Allow` of the paths that are read.
const GET_HEAD: &str = "GET, HEAD";

/// The guided calibration's actions ([`crate::calibrate`]).
const CALIBRATE_PATHS: [&str; 4] =
    ["/api/calibrate/start", "/api/calibrate/step", "/api/calibrate/apply", "/api/calibrate/cancel"];

/// The methods `path` takes, as `Allow` lists them, or `None` when nothing is there: the
/// actions `POST`, the rest `GET` and `HEAD` (the WebSockets too: a `GET` without the upgrade
/// is answered 426, and a `HEAD` with that answer's head).
fn methods(path: &str) -> Option<&'static str> {
    match path {
        p if camera::serves(p) => Some(GET_HEAD),
        "/api/field/start" | "/api/takes/repair" => Some(POST),
        p if CALIBRATE_PATHS.contains(&p) || actions::PATHS.contains(&p) => Some(POST),
        "/" | "/console.js" | "/calibrate.js" | "/console.css" | "/api/hello" | "/api/status"
        | "/api/scene" | "/rig.glb" | "/api/rigs" | "/api/calibrate" | "/api/field" | "/api/takes" => {
            Some(GET_HEAD)
        }
        "/ws" | "/ws/warp" => Some(GET_HEAD),
        "/meadow.js" | "/meadow_rig.js" | "/field.js" => Some(GET_HEAD),
        p if p.starts_with("/api/takes/") || p.starts_with("/api/fields/") || p.starts_with("/api/rigs/") => {
            Some(GET_HEAD)
        }
        p if VENDOR.iter().any(|(v, _)| *v == p) => Some(GET_HEAD),
        _ => None,
    }
}

/// `resp` as a download named `file` (a take's name, checked before: never anything that could
/// leave the quotes; a name that could is sent without the header).
fn download(resp: Response, file: &str) -> Response {
    match attachment(file) {
        Some(v) => resp.with("Content-Disposition", v),
        None => resp,
    }
}

/// The gate's counters for status: connections reading and answering, and what it turned away.
fn gate_json(g: &Gate) -> Value {
    let (reading, answering) = g.load();
    let c = &g.counters;
    json!({
        "reading": reading,
        "answering": answering,
        "admitted": c.admitted.load(Ordering::Relaxed),
        "evicted": c.evicted.load(Ordering::Relaxed),
        "timed_out": c.timed_out.load(Ordering::Relaxed),
        "full": c.full.load(Ordering::Relaxed),
    })
}

impl Site for Console {
    fn answer(&self, req: &Request, _grant: Grant) -> Response {
        self.route(req)
    }

    fn upgrade(&self, req: Request, stream: TcpStream) {
        self.socket(req, stream);
    }

    fn refused(&self, _refusal: &Refusal) {
        self.counters.refused.fetch_add(1, Ordering::Relaxed);
    }
}

/// The request's JSON body (`{}` when empty).
fn json_body(req: &Request) -> Result<Value, Response> {
    if req.body.is_empty() {
        return Ok(json!({}));
    }
    serde_json::from_slice(&req.body).map_err(|e| Response::error(400, format!("the body is not JSON: {e}")))
}

pub(super) fn hello_value(h: &Hello) -> Value {
    json!({
        "rig": h.rig_name,
        "joints": h.joint_names,
        "tick_rate_hz": h.tick_rate_hz,
        "daemon_version": h.daemon_version,
        "elements": h.elements.elements.iter().map(|e| json!({
            "id": e.id, "name": e.name, "kind": e.kind.as_str(), "source": e.source, "rig": e.rig,
        })).collect::<Vec<_>>(),
    })
}
