//! The takes panel: the takes directory listed as `frond take list` has it, a take's main
//! skeleton resampled for playback in the 3D view, and downloads: the GLB frond-gltf bakes and
//! the JSONL `frond take export` prints. Names are checked (`paths::validate_take_name`) before
//! any path is built; files are read only if regular and within the take size limit.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant, SystemTime};

use frond_formats::jsonl::write_pose_line;
use frond_formats::rig_files::RigFileError;
use frond_formats::scan_take;
use frond_gltf::{BakeError, BakeOptions, Baker, LoadedRig, TakeInput};
use frond_motion::field::{Field, FieldParams, make_field};
use frond_motion::{TakeScan, resample, resample_plan};
use frond_protocol::paths;
use serde_json::{Value, json};

/// Most takes listed (the newest by name order beyond are left out, and said so).
pub const MAX_LISTED: usize = 1000;
/// Playback rate of a take in the page, frames per second.
pub const PLAY_FPS: f64 = 60.0;
/// Longest playback sent to the page: 30 minutes at [`PLAY_FPS`].
pub const MAX_PLAY_FRAMES: u64 = 30 * 60 * 60;

/// A takes request that cannot be answered: HTTP status and words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TakeError {
    /// 400, 404, 409, 413 or 500.
    pub status: u16,
    /// What is wrong.
    pub message: String,
}

fn err(status: u16, message: impl Into<String>) -> TakeError {
    TakeError { status, message: message.into() }
}

/// The path of take `name` in `dir`, the name checked first.
fn take_path(dir: &Path, name: &str) -> Result<PathBuf, TakeError> {
    paths::validate_take_name(name).map_err(|e| err(400, e.to_string()))?;
    Ok(dir.join(format!("{name}.take")))
}

/// Take `name`'s path and bytes (a regular file within the take size limit; 404 when absent).
fn read_bytes(dir: &Path, name: &str) -> Result<(PathBuf, Vec<u8>), TakeError> {
    let path = take_path(dir, name)?;
    let bytes = frond_formats::rig_files::read_take_file(&path).map_err(|e| match &e {
        frond_formats::rig_files::FileError::Read { source, .. }
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            err(404, format!("no take {name:?} in {}", dir.display()))
        }
        _ => err(500, e.to_string()),
    })?;
    Ok((path, bytes))
}

fn read(dir: &Path, name: &str) -> Result<(TakeScan, u64), TakeError> {
    let (path, bytes) = read_bytes(dir, name)?;
    let scan = scan_take(&bytes).map_err(|e| err(500, format!("{}: {e}", path.display())))?;
    Ok((scan, bytes.len() as u64))
}

/// Most directory entries looked at for a listing (a directory of millions of files costs no
/// more than this).
pub const MAX_DIR_ENTRIES: usize = 100_000;
/// A take that grew is scanned again at most this often; in between its last summary is shown
/// with its new size (a take being recorded grows all the time). A take that changed otherwise
/// (repaired, replaced) is scanned at its next listing.
pub const RESCAN_EVERY: Duration = Duration::from_secs(1);

/// What identifies a take file's content for the index: length, modification time, inode.
type FileKey = (u64, Option<SystemTime>, u64);

/// One take's summary in the index.
struct Indexed {
    key: FileKey,
    scanned: Instant,
    summary: Value,
}

/// The index of a takes directory: each take's summary (frames, duration, size, state, rig,
/// damage, markers) kept between listings and made again only for a take whose file changed,
/// at most every [`RESCAN_EVERY`]. A listing costs a directory read and a `stat` a take, not a
/// read of every take; one listing runs at a time and the others wait for it.
pub struct TakeIndex {
    dir: PathBuf,
    entries: Mutex<HashMap<String, Indexed>>,
}

impl TakeIndex {
    /// An empty index of `dir`.
    pub fn new(dir: PathBuf) -> TakeIndex {
        TakeIndex { dir, entries: Mutex::default() }
    }

    /// The takes: `{"dir", "takes": [{"name", "frames", "duration_s", "size_bytes", "state",
    /// "rig", "damage", "markers"}], "left_out"}`, sorted by name, at most [`MAX_LISTED`].
    pub fn list(&self) -> Value {
        let dir = &self.dir;
        let mut names: Vec<String> = match std::fs::read_dir(dir) {
            Ok(rd) => rd
                .take(MAX_DIR_ENTRIES)
                .filter_map(Result::ok)
                .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
                .filter_map(|e| e.file_name().to_str()?.strip_suffix(".take").map(str::to_string))
                .filter(|n| paths::validate_take_name(n).is_ok())
                .collect(),
            Err(e) => {
                return json!({ "dir": dir.display().to_string(), "takes": [], "error": format!("cannot list {}: {e}", dir.display()) });
            }
        };
        names.sort();
        let left_out = names.len().saturating_sub(MAX_LISTED);
        names.truncate(MAX_LISTED);
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries.retain(|n, _| names.binary_search(n).is_ok());
        let takes: Vec<Value> = names
            .iter()
            .map(|name| {
                let Some(key) = file_key(&dir.join(format!("{name}.take"))) else {
                    entries.remove(name);
                    return json!({ "name": name, "state": "corrupt", "error": "cannot stat the file" });
                };
                match entries.get_mut(name) {
                    Some(e) if e.key == key => e.summary.clone(),
                    // A take being recorded only grows: its summary is made again at most every
                    // RESCAN_EVERY. Any other change (a repair, a new file) is read at once.
                    Some(e) if grows(e.key, key) && e.scanned.elapsed() < RESCAN_EVERY => {
                        let mut v = e.summary.clone();
                        v["size_bytes"] = json!(key.0);
                        v
                    }
                    _ => {
                        let summary = summarise(dir, name);
                        entries.insert(
                            name.clone(),
                            Indexed { key, scanned: Instant::now(), summary: summary.clone() },
                        );
                        summary
                    }
                }
            })
            .collect();
        json!({ "dir": dir.display().to_string(), "takes": takes, "left_out": left_out })
    }
}

/// Whether a file of key `now` is the file of key `was` grown (the same inode, longer): a take
/// being written.
fn grows(was: FileKey, now: FileKey) -> bool {
    was.2 == now.2 && now.0 > was.0
}

/// A file's [`FileKey`], or `None` when it cannot be looked at.
fn file_key(path: &Path) -> Option<FileKey> {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::symlink_metadata(path).ok()?;
    Some((m.len(), m.modified().ok(), m.ino()))
}

/// One take's summary for the list (the take read once, within the take size limit). Its frames
/// and duration are those of the take's main element, as `frond take list` counts them: the
/// plant's, or a layer take's layer (`TakeScan::main_frame_count`; a take of `frond record
/// layer` holds only its layer's frames).
fn summarise(dir: &Path, name: &str) -> Value {
    match read(dir, name) {
        Ok((scan, size)) => json!({
            "name": name,
            "frames": scan.main_frame_count(),
            "duration_s": scan.duration_s(),
            "size_bytes": size,
            "state": scan.state(size),
            "rig": scan.header.as_ref().map(|h| h.rig_name.clone()),
            "damage": scan.damage(),
            "markers": scan.markers.len(),
        }),
        Err(e) => json!({ "name": name, "state": "corrupt", "error": e.message }),
    }
}

/// Take `name`'s main skeleton resampled to [`PLAY_FPS`] for the page: `{"name", "rig", "fps",
/// "frames": [[[pitch, yaw, roll] x 4], ...]}`.
pub fn playback(dir: &Path, name: &str) -> Result<Value, TakeError> {
    let (scan, _) = read(dir, name)?;
    let poses = scan.poses();
    if poses.is_empty() {
        return Err(err(400, format!("take {name:?} has no frames of the main skeleton")));
    }
    resample_plan(&poses, PLAY_FPS).check(PLAY_FPS, MAX_PLAY_FRAMES).map_err(|e| {
        err(413, format!("take {name:?}: {e}: longer than the page plays (export it instead)"))
    })?;
    let frames: Vec<_> = resample(&poses, PLAY_FPS).iter().map(|p| p.joints_deg).collect();
    Ok(json!({
        "name": name,
        "rig": scan.header.as_ref().map(|h| h.rig_name.clone()),
        "fps": PLAY_FPS,
        "frames": frames,
    }))
}

/// Rate a field started from the page samples its take at, frames per second (as `frond take
/// field`'s default).
pub const FIELD_FPS: f64 = 30.0;

/// Most rows, and most columns, of a field started from the page.
pub const MAX_FIELD_SIDE: u64 = 16;
/// Most plants of a field started from the page.
pub const MAX_FIELD_PLANTS: u64 = 64;
/// Largest cell of a field started from the page, metres (a 16-cell row is then 1.6 km long;
/// the force crosses it in 18 minutes at 1.5 m/s, within the field's delay limit).
pub const MAX_FIELD_CELL_M: f64 = 100.0;

/// What the page's "Field" button asks: `{"take", "rows"?, "cols"?, "plants"?, "cell_m"?}`.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldRequest {
    /// The take the plants play.
    pub take: String,
    /// Rows of the grid (default 4).
    pub rows: usize,
    /// Columns of the grid (default 4).
    pub cols: usize,
    /// Plants the daemon plays (default 16, at most one a cell).
    pub plants: u16,
    /// Side of a cell, metres (default 0.3).
    pub cell_m: f64,
    /// The plants' rig, an embedded rig's name (default: the daemon's rig).
    pub rig: Option<String>,
    /// The field's stage name (default `field`): fields under other names play beside it.
    pub name: Option<String>,
}

impl FieldRequest {
    /// The request in a JSON body, every value checked here and named by its JSON key (the
    /// field's own checks name `frond take field`'s options, which mean nothing to the page).
    pub fn from_json(body: &Value) -> Result<FieldRequest, TakeError> {
        let bad = |m: String| err(400, m);
        let Some(take) = body.get("take").and_then(Value::as_str) else {
            return Err(bad("field start needs {\"take\": \"...\"}".into()));
        };
        let int = |key: &str, default: u64, max: u64| match body.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_u64()
                .filter(|n| (1..=max).contains(n))
                .ok_or_else(|| bad(format!("{key} must be an integer 1..={max}, got {v}"))),
        };
        let rows = int("rows", 4, MAX_FIELD_SIDE)? as usize;
        let cols = int("cols", 4, MAX_FIELD_SIDE)? as usize;
        let plants = int("plants", 16, MAX_FIELD_PLANTS)? as u16;
        let cell_m = match body.get("cell_m") {
            None => 0.3,
            Some(v) => v.as_f64().filter(|m| *m > 0.0 && *m <= MAX_FIELD_CELL_M).ok_or_else(|| {
                bad(format!("cell_m must be a number of metres > 0 and <= {MAX_FIELD_CELL_M}, got {v}"))
            })?,
        };
        let rig = match body.get("rig") {
            None => None,
            Some(v) => match v.as_str() {
                Some(r) if frond_formats::rig_files::EMBEDDED_RIGS.iter().any(|(n, _)| *n == r) => {
                    Some(r.to_string())
                }
                _ => {
                    let names: Vec<&str> =
                        frond_formats::rig_files::EMBEDDED_RIGS.iter().map(|(n, _)| *n).collect();
                    return Err(bad(format!("rig must be an embedded rig's name ({})", names.join(", "))));
                }
            },
        };
        let name = match body.get("name") {
            None => None,
            Some(v) => match v.as_str() {
                Some(n) if is_stage_name(n) => Some(n.to_string()),
                _ => return Err(bad("name must be 1 to 32 letters, digits, '-' or '_'".into())),
            },
        };
        Ok(FieldRequest { take: take.to_string(), rows, cols, plants, cell_m, rig, name })
    }
}

/// The layout's seed of a field of `rig` started from the page: 1 for the daemon's rig, and
/// each embedded rig its own, so that fields of several rigs on one grid interleave (each cell
/// a plant of each, placed apart) rather than stand in one another.
fn layout_seed(rig: Option<&str>) -> u64 {
    let embedded = frond_formats::rig_files::EMBEDDED_RIGS.iter();
    rig.and_then(|r| embedded.clone().position(|(n, _)| *n == r)).map_or(1, |k| 2 + k as u64)
}

/// Whether `name` is a stage name the daemon takes: 1 to 32 ASCII letters, digits, `-`, `_`.
pub fn is_stage_name(name: &str) -> bool {
    (1..=32).contains(&name.len())
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

/// The field `ask` names for the page's "Field" button (seed 000, section 6.2): a `rows x cols`
/// grid of `cell_m` cells, the force along +X at 1.5 m/s, every cell planted; as
/// `frond take field NAME --rows R --cols C --cell M --speed 1.5` writes it.
pub fn field(dir: &Path, ask: &FieldRequest) -> Result<Field, TakeError> {
    let name = ask.take.as_str();
    let (scan, _) = read(dir, name)?;
    let poses = scan.poses();
    if poses.is_empty() {
        return Err(err(400, format!("take {name:?} has no frames of the main skeleton")));
    }
    let plan = resample_plan(&poses, FIELD_FPS);
    plan.check(FIELD_FPS, MAX_PLAY_FRAMES).map_err(|e| err(413, format!("take {name:?}: {e}")))?;
    let params = FieldParams {
        rows: ask.rows,
        cols: ask.cols,
        cell_m: ask.cell_m,
        speed_m_s: 1.5,
        direction_deg: 0.0,
        density: 1.0,
        seed: layout_seed(ask.rig.as_deref()),
    };
    make_field(&params, name, plan.frames as usize, FIELD_FPS).map_err(|e| err(400, e.to_string()))
}

/// Repairs take `name` as `frond take repair NAME` does (`frond_formats::take_repair`): the
/// readable records kept, the rest dropped, closed with an End record; refused while it may
/// still be recording. `{"repaired": bool, "message"}`.
pub fn repair(dir: &Path, name: &str) -> Result<Value, TakeError> {
    use frond_formats::take_repair::{MAY_BE_RECORDING, repaired_bytes};
    let (path, bytes) = read_bytes(dir, name)?;
    let Some((fixed, r)) =
        repaired_bytes(&bytes).map_err(|e| err(409, format!("{}: {e}", path.display())))?
    else {
        return Ok(json!({ "repaired": false, "message": format!("{name} is complete; nothing to repair") }));
    };
    let age = std::fs::metadata(&path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|m| std::time::SystemTime::now().duration_since(m).ok())
        .unwrap_or(std::time::Duration::MAX);
    if !r.closed_before() && age < MAY_BE_RECORDING {
        return Err(err(
            409,
            format!(
                "{name} was modified {:.1} s ago and may still be recording; stop the recording first",
                age.as_secs_f64()
            ),
        ));
    }
    frond_formats::rig_files::write_file_atomically(&path, &fixed)
        .map_err(|e| err(500, format!("cannot write {}: {e}", path.display())))?;
    Ok(json!({ "repaired": true, "message": r.report(&path.display().to_string()) }))
}

/// Take `name` as JSONL, one pose per line, as `frond take export NAME` prints it (main
/// skeleton, held frames left out, at the recorded times).
pub fn jsonl(dir: &Path, name: &str) -> Result<String, TakeError> {
    let (scan, _) = read(dir, name)?;
    let mut out = String::new();
    for pose in &scan.main_poses(false) {
        write_pose_line(pose, None, &mut out);
        out.push('\n');
    }
    Ok(out)
}

/// Take `name` baked by frond-gltf on the rig it was recorded on: the header's rig (else
/// `daemons_rig`, the connected daemon's) when that is an embedded rig; a rig loaded from a
/// file keeps only its name, which is never opened as a path (`recorded_rig`: a take must not
/// make the console read a file it names), so such a take is baked on the console's own `--rig`
/// (`own_rig`) or refused, 409, with the way to start the console that bakes it.
pub fn glb(
    dir: &Path,
    name: &str,
    daemons_rig: Option<&str>,
    own_rig: Option<&LoadedRig>,
) -> Result<Vec<u8>, TakeError> {
    let (path, bytes) = read_bytes(dir, name)?;
    let take = TakeInput::from_bytes(&bytes, name, &path.display().to_string())
        .map_err(|e| err(500, e.to_string()))?;
    let recorded_on =
        take.header.as_ref().map(|h| h.rig_name.as_str()).filter(|n| !n.is_empty()).or(daemons_rig);
    let rig = match (recorded_on, own_rig) {
        (Some(rig_name), own) => match LoadedRig::recorded(rig_name) {
            Ok(rig) => rig,
            Err(BakeError::Rig(RigFileError::NotEmbedded { embedded, .. })) => match own {
                Some(own) => own.clone(),
                None => {
                    return Err(err(
                        409,
                        format!(
                            "take {name:?} was recorded on rig {rig_name:?}, which is not an embedded rig \
                             ({embedded}): a rig file is not opened by the name a take keeps; start \
                             frond-console with --rig FILE (that rig's file) to bake it"
                        ),
                    ));
                }
            },
            Err(e) => return Err(err(500, format!("rig {rig_name:?}: {e}"))),
        },
        (None, Some(own)) => own.clone(),
        (None, None) => {
            return Err(err(400, format!("take {name:?} names no rig and the daemon's is not known")));
        }
    };
    let model = rig.model().map_err(|e| err(500, e.to_string()))?;
    let baked = Baker::new()
        .bake_take(&rig, &model, &take, &BakeOptions::default(), &mut |_, _| {})
        .map_err(|e| match e {
            BakeError::TooManyKeys { keys, fps, limit, .. } => too_long_to_bake(name, keys, fps, limit),
            e => err(500, e.to_string()),
        })?;
    let mut out = Vec::new();
    frond_gltf::encode_glb(&baked, &mut out).map_err(|e| err(500, e.to_string()))?;
    Ok(out)
}

/// The answer for a take longer than frond-gltf bakes (`keys` keys at `fps`, past `limit`):
/// the page's user's mistake, not the server's (413, as a playback too long for the page), in
/// times rather than keys, with what the page offers instead.
fn too_long_to_bake(name: &str, keys: u64, fps: f64, limit: u64) -> TakeError {
    // Key k is at k / fps, so n keys span (n - 1) / fps.
    let span = |keys: u64| keys.saturating_sub(1) as f64 / fps;
    err(
        413,
        format!(
            "take {name:?} is {} long; a GLB download holds at most {} ({limit} keys at {fps} FPS): \
             download its JSONL instead",
            human_duration(span(keys)),
            human_duration(span(limit)),
        ),
    )
}

/// `s` seconds as hours, minutes and seconds (`10 h 1 min 39 s`, `10 h`, `0 s`), to the second.
fn human_duration(s: f64) -> String {
    let total = s.max(0.0).round() as u64;
    let (h, min, sec) = (total / 3600, total / 60 % 60, total % 60);
    let parts: Vec<String> = [(h, "h"), (min, "min"), (sec, "s")]
        .iter()
        .filter(|(n, _)| *n > 0)
        .map(|(n, unit)| format!("{n} {unit}"))
        .collect();
    if parts.is_empty() { "0 s".into() } else { parts.join(" ") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked_before_any_path_is_built() {
        let dir = tempfile::tempdir().unwrap();
        for bad in ["../x", "a/b", "", ".hidden"] {
            let e = playback(dir.path(), bad).unwrap_err();
            assert_eq!(e.status, 400, "{bad:?}: {e:?}");
        }
        let e = playback(dir.path(), "missing").unwrap_err();
        assert_eq!(e.status, 404);
        assert!(e.message.contains("no take \"missing\""), "{e:?}");
    }

    #[test]
    fn a_directory_that_is_not_there_lists_nothing_and_says_why() {
        let v = TakeIndex::new("/nonexistent/frond-takes".into()).list();
        assert_eq!(v["takes"], json!([]));
        assert!(v["error"].as_str().unwrap().contains("cannot list"), "{v}");
    }

    #[test]
    fn durations_read_as_hours_minutes_and_seconds() {
        assert_eq!(human_duration(36099.0), "10 h 1 min 39 s");
        assert_eq!(human_duration(35999.97), "10 h");
        assert_eq!(human_duration(61.4), "1 min 1 s");
        assert_eq!(human_duration(0.2), "0 s");
    }

    #[test]
    fn field_requests_name_their_json_keys() {
        let ok = FieldRequest::from_json(&json!({"take": "t"})).unwrap();
        assert_eq!(
            ok,
            FieldRequest {
                take: "t".into(),
                rows: 4,
                cols: 4,
                plants: 16,
                cell_m: 0.3,
                rig: None,
                name: None
            }
        );
        let flowers =
            FieldRequest::from_json(&json!({"take": "t", "rig": "flower", "name": "flowers"})).unwrap();
        assert_eq!((flowers.rig.as_deref(), flowers.name.as_deref()), (Some("flower"), Some("flowers")));
        for (body, key) in [
            (json!({"take": "t", "cell_m": -1}), "cell_m"),
            (json!({"take": "t", "cell_m": 0}), "cell_m"),
            (json!({"take": "t", "cell_m": 1000}), "cell_m"),
            (json!({"take": "t", "cell_m": "wide"}), "cell_m"),
            (json!({"take": "t", "rows": 0}), "rows"),
            (json!({"take": "t", "cols": 17}), "cols"),
            (json!({"take": "t", "plants": 1.5}), "plants"),
            (json!({"rows": 2}), "take"),
            (json!({"take": "t", "rig": "/etc/passwd"}), "rig must be an embedded rig's name (grass"),
            (json!({"take": "t", "rig": 3}), "rig"),
            (json!({"take": "t", "name": "a b"}), "name must be"),
            (json!({"take": "t", "name": ""}), "name must be"),
        ] {
            let e = FieldRequest::from_json(&body).unwrap_err();
            assert_eq!(e.status, 400, "{body}");
            assert!(e.message.contains(key) && !e.message.contains("--"), "{body}: {}", e.message);
        }
    }
}
