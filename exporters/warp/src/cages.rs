//! The cage mode's files and commands (seed 004): a layer's matte, `cage.json`, `cage build`
//! and `cage coords`. The geometry itself is the `frond_cage` crate.

use std::path::Path;

use frond_cage::mvc::mean_value_coordinates;
use frond_cage::tree::contains;
use frond_cage::{BuildOptions, CageTree, Point, build_cage_tree};
use frond_formats::rig_files::{FileError, read_small_text};
use thiserror::Error;

use crate::layers::{SceneError, read_image};

/// Largest `cage.json` read, bytes (the most vertices a tree may have, written out, fit well).
pub const MAX_CAGE_FILE_BYTES: u64 = 32 << 20;
/// Most `--at` points of one `cage coords`.
pub const MAX_QUERY_POINTS: usize = 100_000;

/// Why a cage command failed.
#[derive(Debug, Error)]
pub enum CageCommandError {
    /// The layer could not be read.
    #[error(transparent)]
    Layer(#[from] SceneError),
    /// The cage file could not be read.
    #[error("cannot read cage file {}: {}", .0.path().display(), .0.reason())]
    File(FileError),
    /// The cage file is not valid.
    #[error("cage file {path}: {error}")]
    Cage {
        /// The file.
        path: String,
        /// What is wrong.
        error: frond_cage::CageError,
    },
    /// No tree could be built.
    #[error("layer {path}: {error}")]
    Build {
        /// The layer.
        path: String,
        /// Why.
        error: frond_cage::build::BuildError,
    },
    /// A bad argument.
    #[error("{0}")]
    Argument(String),
}

/// A layer's matte: a greyscale mask's luminance, or an RGBA image's alpha (what makes a pixel
/// vegetation in [`crate::Scene`] too).
pub fn read_matte(path: &Path) -> Result<(Vec<u8>, usize, usize), SceneError> {
    let img = read_image("layer", path)?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let matte = if img.color().has_alpha() && img.color().has_color() {
        img.to_rgba8().pixels().map(|p| p.0[3]).collect()
    } else {
        img.to_luma8().into_raw()
    };
    Ok((matte, w, h))
}

/// Reads and validates a `cage.json`.
pub fn read_cage_file(path: &Path) -> Result<CageTree, CageCommandError> {
    let text = read_small_text(path, MAX_CAGE_FILE_BYTES).map_err(CageCommandError::File)?;
    CageTree::from_json(&text)
        .map_err(|error| CageCommandError::Cage { path: path.display().to_string(), error })
}

/// `cage build`: the tree of `layer` as `cage.json` text.
pub fn build_file(layer: &Path, opts: &BuildOptions) -> Result<(CageTree, String), CageCommandError> {
    let problems = opts.problems();
    if !problems.is_empty() {
        return Err(CageCommandError::Argument(problems.join("; ")));
    }
    let (matte, w, h) = read_matte(layer)?;
    let tree = build_cage_tree(&matte, w, h, opts)
        .map_err(|error| CageCommandError::Build { path: layer.display().to_string(), error })?;
    let text = tree.to_json();
    Ok((tree, text))
}

/// Writes `text` to `path` atomically ([`frond_formats::rig_files::write_file_atomically`]).
pub fn write_file(path: &Path, text: &str) -> std::io::Result<()> {
    frond_formats::rig_files::write_file_atomically(path, text.as_bytes())
}

/// A point argument that is not `X,Y` of finite numbers (named `--at` as `cage coords` takes it;
/// `--anchor` reports it under its own name too).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--at {text:?}: expected X,Y in image pixels, e.g. 120.5,80")]
pub struct BadPoint {
    /// The argument as given.
    pub text: String,
}

/// Parses `X,Y` (finite numbers).
pub fn parse_point(text: &str) -> Result<Point, BadPoint> {
    let bad = || BadPoint { text: text.to_string() };
    let (x, y) = text.split_once(',').ok_or_else(bad)?;
    let (x, y): (f64, f64) = (x.trim().parse().map_err(|_| bad())?, y.trim().parse().map_err(|_| bad())?);
    if !(x.is_finite() && y.is_finite()) {
        return Err(bad());
    }
    Ok([x, y])
}

/// `cage coords`: the mean value coordinates of `points` for cage `id`, as JSON:
/// `{"cage":ID,"vertices":N,"points":[{"at":[x,y],"inside":bool,"weights":[...]}, ...]}`.
pub fn coords_json(tree: &CageTree, id: u32, points: &[String]) -> Result<String, CageCommandError> {
    if points.len() > MAX_QUERY_POINTS {
        return Err(CageCommandError::Argument(format!(
            "{} --at points; at most {MAX_QUERY_POINTS}",
            points.len()
        )));
    }
    let index = tree.index_of(id).ok_or_else(|| {
        let ids: Vec<String> = tree.cages.iter().map(|c| c.id.to_string()).take(20).collect();
        CageCommandError::Argument(format!("--id {id}: no such cage (ids: {})", ids.join(", ")))
    })?;
    let parsed: Result<Vec<Point>, BadPoint> = points.iter().map(|p| parse_point(p)).collect();
    let parsed = parsed.map_err(|e| CageCommandError::Argument(e.to_string()))?;
    let cage = &tree.cages[index].vertices;
    let mut weights = Vec::new();
    let mut rows = Vec::with_capacity(parsed.len());
    for at in parsed {
        mean_value_coordinates(cage, at, &mut weights);
        rows.push(serde_json::json!({ "at": at, "inside": contains(cage, at), "weights": weights }));
    }
    let out = serde_json::json!({ "cage": id, "vertices": cage.len(), "points": rows });
    Ok(serde_json::to_string(&out).expect("JSON of numbers"))
}
