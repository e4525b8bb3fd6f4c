//! Reading what a bake needs from disk: rigs (embedded or files), their meshes, and takes (by
//! name in the takes directory, or by path). The document builder itself ([`crate::bake`]) is
//! pure and works on what these functions return.

use std::path::{Path, PathBuf};

use frond_formats::scan_take;
use frond_motion::mesh::PlantModel;
use frond_motion::{Rig, TakeFrame, TakeHeader};
use frond_protocol::ElementId;

use crate::error::BakeError;

/// The rigs of `rig-files/plants/`, built into the binary: `(name, TOML text)`.
pub use frond_formats::rig_files::EMBEDDED_RIGS;

/// A validated rig and where it came from.
#[derive(Debug, Clone)]
pub struct LoadedRig {
    /// The rig.
    pub rig: Rig,
    /// `embedded rig grass` or the file path, for messages.
    pub origin: String,
    /// Directory of the rig file (mesh files are relative to it); `None` when embedded.
    pub dir: Option<PathBuf>,
}

impl From<frond_formats::rig_files::LoadedRig> for LoadedRig {
    fn from(l: frond_formats::rig_files::LoadedRig) -> Self {
        LoadedRig { rig: l.rig, origin: l.origin, dir: l.dir }
    }
}

impl LoadedRig {
    /// Parses a rig from TOML text (no I/O). `origin` names it in errors.
    pub fn from_toml(text: &str, origin: impl Into<String>, dir: Option<PathBuf>) -> Result<Self, BakeError> {
        let origin = origin.into();
        Ok(frond_formats::rig_files::rig_from_text(text.to_string(), origin, "", dir)?.into())
    }

    /// An embedded rig by name (`grass`, `flower`, `shrub`).
    pub fn embedded(name: &str) -> Option<Result<Self, BakeError>> {
        frond_formats::rig_files::embedded_rig(name).map(|r| Ok(r?.into()))
    }

    /// `--rig`: a file path (with `/` or ending in `.toml`), else an embedded rig name, else a
    /// file of that name (the one rig loader, `frond_formats::rig_files`).
    pub fn resolve(arg: &str) -> Result<Self, BakeError> {
        Ok(frond_formats::rig_files::load_rig(arg)?.into())
    }

    /// The rig a take was recorded on (or a daemon reports), by the name it keeps: an embedded
    /// rig only, never a path (`frond_formats::rig_files::recorded_rig`): the name comes from a
    /// file or a peer, and must not make a baker read a file it names. A rig loaded from a file
    /// is refused (`RigFileError::NotEmbedded`); the caller asks for it with `--rig FILE`.
    pub fn recorded(name: &str) -> Result<Self, BakeError> {
        Ok(frond_formats::rig_files::recorded_rig(name)?.into())
    }

    /// The plant geometry: the procedural shape the rig names, or its glTF/GLB mesh file (read
    /// relative to the rig file, skin weights from the file where it has them), by
    /// `frond_formats::rig_files::plant_model`.
    pub fn model(&self) -> Result<PlantModel, BakeError> {
        let loaded = frond_formats::rig_files::LoadedRig {
            rig: self.rig.clone(),
            text: String::new(),
            origin: self.origin.clone(),
            dir: self.dir.clone(),
        };
        frond_formats::rig_files::plant_model(&loaded)
            .map_err(|e| BakeError::RigMesh { origin: e.origin, reason: e.reason })
    }
}

/// A take's content, ready to bake.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TakeInput {
    /// Take name (the animation's name).
    pub name: String,
    /// The header record, when the take has one.
    pub header: Option<TakeHeader>,
    /// Names of secondary layers `1, 2, ...` from the header (`elements`), possibly fewer.
    pub element_names: Vec<String>,
    /// Every frame, all elements, in file order.
    pub frames: Vec<TakeFrame>,
    /// Bytes of a torn tail that were skipped (a take still being written, or a crash).
    pub torn_bytes: u64,
    /// True when the take has its End record.
    pub ended: bool,
    /// What the reader skipped in a damaged take, in words (`None` when sound).
    pub damage: Option<String>,
}

impl TakeInput {
    /// Reads a take from its bytes (no I/O). `name` is used when the header has none;
    /// `origin` names it in errors.
    pub fn from_bytes(bytes: &[u8], name: &str, origin: &str) -> Result<Self, BakeError> {
        let scan = scan_take(bytes)
            .map_err(|source| BakeError::TakeDamaged { origin: origin.to_string(), source })?;
        let damage = scan.damage();
        let name = scan
            .header
            .as_ref()
            .map(|h| h.name.clone())
            .filter(|n| !n.is_empty())
            .unwrap_or_else(|| name.to_string());
        Ok(TakeInput {
            name,
            header: scan.header,
            element_names: frond_formats::layers::header_element_names(bytes),
            frames: scan.frames,
            torn_bytes: scan.torn_bytes,
            ended: scan.ended,
            damage,
        })
    }

    /// `--take`: a path (contains `/`, ends in `.take`, or is an existing file), else a take name
    /// in `takes_dir`.
    pub fn resolve(arg: &str, takes_dir: &Path) -> Result<Self, BakeError> {
        let path = take_path(arg, takes_dir)?;
        let bytes = frond_formats::rig_files::read_take_file(&path).map_err(|e| match e {
            frond_formats::rig_files::FileError::Read { source, .. }
                if source.kind() == std::io::ErrorKind::NotFound =>
            {
                BakeError::TakeNotFound { arg: arg.to_string(), path: path.clone() }
            }
            other => BakeError::TakeFile(other),
        })?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or(arg).to_string();
        Self::from_bytes(&bytes, &stem, &path.display().to_string())
    }
}

/// Where `--take ARG` points: see [`TakeInput::resolve`].
pub fn take_path(arg: &str, takes_dir: &Path) -> Result<PathBuf, BakeError> {
    frond_protocol::paths::take_file(arg, takes_dir)
        .map_err(|reason| BakeError::TakeName { arg: arg.to_string(), reason })
}

impl TakeInput {
    /// The name of layer `id` (> 0): the take's own name for it, else the rig's element of the
    /// same index (takes recorded before layer names), else `element<id>`.
    pub fn layer_name(&self, id: ElementId, rig: &frond_motion::Rig) -> String {
        let k = id.index().saturating_sub(1);
        self.element_names
            .get(k)
            .or_else(|| rig.elements.get(k).map(|e| &e.name))
            .cloned()
            .unwrap_or_else(|| format!("element{id}"))
    }
}
