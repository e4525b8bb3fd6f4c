//! The camera panel (issue 47): what a `webcam` hand source sees, for the operator.
//!
//! The landmark helper `frond-hands` keeps a small JPEG of its latest frame with the hand's
//! bones and landmarks drawn (a few times a second, replaced atomically) in the daemon's socket
//! directory, which only the daemon's user and group may enter, and the daemon's status names
//! it ([`frond_protocol::CameraStatus::preview`]). The console serves it to its own page only:
//!
//! - behind the access rules every endpoint has (a loopback `Host` literal, the token beyond
//!   loopback, Fetch Metadata refusing another site's requests), and with
//!   `Cross-Origin-Resource-Policy: same-origin`, so a browser that sends no Fetch Metadata
//!   still keeps the picture from another site's page;
//! - only a name the daemon's status gives now and [`frond_protocol::paths::is_camera_preview_name`]
//!   accepts, joined to the console's own `--socket-dir`: nothing from a request or the daemon
//!   names any other file;
//! - only a regular file of at most [`MAX_PREVIEW_BYTES`] that starts as a JPEG does, not older
//!   than [`MAX_PREVIEW_AGE`] (a stopped helper's last picture is not shown as live).
//!
//! Endpoints: `GET /camera.js` the panel's script; `GET /api/camera` the cameras (source,
//! frame rate and latency, the picture's URL) and the primary hand's latest raw sample (the
//! angles derived from the landmarks, before calibration); `GET /api/camera/webcam-N.jpg` the
//! picture.

use std::path::Path;
use std::time::{Duration, SystemTime};

use frond_protocol::paths::is_camera_preview_name;
use frond_protocol::{ControlReply, ControlRequest, StatusReport};
use frond_web::http::{HeaderValue, Request, Response};
use serde_json::{Value, json};

use super::Console;

/// The panel's script.
pub(super) const CAMERA_JS: &str = include_str!("../../page/camera.js");
/// Largest preview picture served, bytes (the helper's are about 10-30 KB).
pub const MAX_PREVIEW_BYTES: u64 = 1 << 20;
/// Oldest preview picture served: the helper writes several a second.
pub const MAX_PREVIEW_AGE: Duration = Duration::from_secs(3);
/// Where the pictures are served.
const IMAGE_PREFIX: &str = "/api/camera/";

/// Whether `path` is one of the panel's (all `GET` and `HEAD`).
pub(super) fn serves(path: &str) -> bool {
    path == "/camera.js" || path == "/api/camera" || path.starts_with(IMAGE_PREFIX)
}

impl Console {
    /// `GET` of a path [`serves`] accepts.
    pub(super) fn camera(&self, req: &Request) -> Response {
        match req.path.as_str() {
            "/camera.js" => Response::new(200, "text/javascript; charset=utf-8", CAMERA_JS),
            "/api/camera" => self.cameras(),
            p => self.camera_image(&p[IMAGE_PREFIX.len()..]),
        }
    }

    fn cameras(&self) -> Response {
        let report = match self.daemon.status() {
            Ok(r) => r,
            Err(e) => {
                return Response::json(200, &json!({ "cameras": [], "raw": null, "error": e.to_string() }));
            }
        };
        let cameras = cameras_json(&report);
        // The angles the daemon derived from the landmarks (the primary hand's, uncalibrated):
        // asked only when a camera drives a hand.
        let raw = match cameras.is_empty() {
            true => Value::Null,
            false => match self.daemon.request(&ControlRequest::RawSample) {
                Ok(ControlReply::RawSample { t, wrist_deg, thumb_deg, fresh }) => {
                    json!({ "t": t, "wrist_deg": wrist_deg, "thumb_deg": thumb_deg, "fresh": fresh })
                }
                _ => Value::Null,
            },
        };
        let primary = report.hands.first().map(|h| h.name.clone());
        Response::json(200, &json!({ "cameras": cameras, "primary": primary, "raw": raw }))
    }

    fn camera_image(&self, name: &str) -> Response {
        if !is_camera_preview_name(name) {
            return Response::error(404, "no such camera picture (webcam-N.jpg)");
        }
        // Only a picture the daemon names now: not one of a source that was replaced.
        let named = self.daemon.status().is_ok_and(|r| {
            r.hands.iter().any(|h| h.source.camera.as_ref().and_then(|c| c.preview.as_deref()) == Some(name))
        });
        if !named {
            return Response::error(404, format!("the daemon names no camera picture {name}"));
        }
        match read_preview(&self.config.socket_dir.join(name)) {
            Ok(jpeg) => Response::new(200, "image/jpeg", jpeg)
                .with("Cross-Origin-Resource-Policy", HeaderValue::from_static("same-origin")),
            Err(why) => Response::error(503, why),
        }
    }
}

/// The cameras among the daemon's hands, for the page: `[{"hand", "kind", "path", "connected",
/// "camera": CameraStatus, "image": "/api/camera/webcam-N.jpg" | null}]`.
fn cameras_json(report: &StatusReport) -> Vec<Value> {
    report
        .hands
        .iter()
        .filter_map(|h| {
            let camera = h.source.camera.as_ref()?;
            let image = camera.preview.as_deref().filter(|n| is_camera_preview_name(n));
            Some(json!({
                "hand": h.name,
                "kind": h.source.kind,
                "path": h.source.path,
                "connected": h.source.connected,
                "camera": camera,
                "image": image.map(|n| format!("{IMAGE_PREFIX}{n}")),
            }))
        })
        .collect()
}

/// The picture at `path`: a regular file of at most [`MAX_PREVIEW_BYTES`], at most
/// [`MAX_PREVIEW_AGE`] old, that starts as a JPEG does; else why not, in words.
fn read_preview(path: &Path) -> Result<Vec<u8>, String> {
    let jpeg = frond_formats::rig_files::read_small_file(path, MAX_PREVIEW_BYTES).map_err(|e| match e {
        frond_formats::rig_files::FileError::Read { ref source, .. }
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            "the camera has no picture yet (is its helper, frond-hands, running?)".to_string()
        }
        e => e.reason(),
    })?;
    let age = std::fs::metadata(path)
        .and_then(|m| m.modified())
        .map(|t| SystemTime::now().duration_since(t).unwrap_or_default())
        .map_err(|e| e.to_string())?;
    if age > MAX_PREVIEW_AGE {
        return Err(format!(
            "the camera's last picture is {:.0} s old: its helper is not running (frond status says why)",
            age.as_secs_f64()
        ));
    }
    if !jpeg.starts_with(&[0xFF, 0xD8, 0xFF]) {
        return Err("the camera's picture is not a JPEG".into());
    }
    Ok(jpeg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    #[test]
    fn only_a_small_fresh_regular_jpeg_is_served() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("webcam-1.jpg");
        std::fs::write(&good, [0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3]).unwrap();
        assert_eq!(read_preview(&good).unwrap().len(), 7);
        let missing = read_preview(&dir.path().join("webcam-2.jpg")).unwrap_err();
        assert!(missing.contains("no picture yet"), "{missing}");
        let text = dir.path().join("webcam-3.jpg");
        std::fs::write(&text, "<script>").unwrap();
        assert!(read_preview(&text).unwrap_err().contains("not a JPEG"));
        let big = dir.path().join("webcam-4.jpg");
        std::fs::File::create(&big).unwrap().set_len(MAX_PREVIEW_BYTES + 1).unwrap();
        assert!(read_preview(&big).is_err());
        let fifo = dir.path().join("webcam-5.jpg");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        assert!(read_preview(&fifo).is_err(), "a FIFO is refused without blocking");
        let old = dir.path().join("webcam-6.jpg");
        std::fs::write(&old, [0xFF, 0xD8, 0xFF]).unwrap();
        let f = std::fs::File::options().write(true).open(&old).unwrap();
        f.set_modified(SystemTime::now() - Duration::from_secs(10)).unwrap();
        assert!(read_preview(&old).unwrap_err().contains("10 s old"));
        let link = dir.path().join("webcam-7.jpg");
        symlink("/dev/zero", &link).unwrap();
        assert!(read_preview(&link).is_err(), "a link to a device is refused");
    }
}
