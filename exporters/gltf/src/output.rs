//! Writing a baked document: one binary `.glb`, or `.gltf` + `.bin`. Every file is written to
//! a temporary file in the destination directory, flushed to disk, then renamed over the
//! destination, so an error (or a crash) never leaves a half-written file behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::bake::Baked;
use crate::error::BakeError;

/// Output container.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// One binary `.glb` file.
    #[default]
    Glb,
    /// A `.gltf` JSON file and a `.bin` file beside it.
    Gltf,
}

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Encodes a document as GLB (glTF 2.0 binary container) into `out` (cleared first).
pub fn encode_glb(baked: &Baked, out: &mut Vec<u8>) -> Result<(), BakeError> {
    let mut json = serde_json::to_vec(&baked.root).map_err(|e| BakeError::Json(e.to_string()))?;
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin_padded = baked.bin.len().next_multiple_of(4);
    let total = 12 + 8 + json.len() + 8 + bin_padded;
    let total32 = u32::try_from(total).map_err(|_| {
        BakeError::Json(format!("the document is {total} bytes, more than GLB's 4 GiB limit"))
    })?;
    out.clear();
    out.reserve(total);
    out.extend_from_slice(GLB_MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin_padded as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&baked.bin);
    out.resize(total, 0);
    Ok(())
}

/// The `.bin` path of a `.gltf` output: same directory and stem.
pub fn bin_path(gltf: &Path) -> PathBuf {
    gltf.with_extension("bin")
}

/// Writes `baked` to `path` in `format`. For [`Format::Gltf`] the buffer goes to
/// [`bin_path`] and the JSON refers to it by file name.
pub fn write(baked: &mut Baked, path: &Path, format: Format) -> Result<(), BakeError> {
    let path = &destination(path)?;
    match format {
        Format::Glb => {
            let mut bytes = Vec::new();
            encode_glb(baked, &mut bytes)?;
            let tmp = write_temp(path, &bytes)?;
            persist(tmp, path)
        }
        Format::Gltf => {
            let bin = destination(&bin_path(path))?;
            let name = bin.file_name().and_then(|n| n.to_str()).map(str::to_string).ok_or_else(|| {
                BakeError::Output {
                    path: path.to_path_buf(),
                    reason: "the file name is not UTF-8".to_string(),
                }
            })?;
            baked.root.buffers[0].uri = Some(name);
            let json = serde_json::to_vec_pretty(&baked.root).map_err(|e| BakeError::Json(e.to_string()));
            baked.root.buffers[0].uri = None;
            let json = json?;
            // Both written and synced before either is renamed into place.
            let bin_tmp = write_temp(&bin, &baked.bin)?;
            let json_tmp = write_temp(path, &json)?;
            persist(bin_tmp, &bin)?;
            persist(json_tmp, path)
        }
    }
}

fn output_err(path: &Path, reason: impl Into<String>) -> BakeError {
    BakeError::Output { path: path.to_path_buf(), reason: reason.into() }
}

/// Where `path` may be written ([`frond_formats::rig_files::output_destination`]): never over a
/// device, FIFO or directory, through a symbolic link to its file, into a directory that exists.
fn destination(path: &Path) -> Result<PathBuf, BakeError> {
    frond_formats::rig_files::output_destination(path).map_err(|e| output_err(path, e.to_string()))
}

fn write_temp(path: &Path, bytes: &[u8]) -> Result<tempfile::NamedTempFile, BakeError> {
    let dir = frond_formats::rig_files::parent_dir(path);
    // Like any new file: 0666 less the umask (a temporary file defaults to 0600).
    let mode = std::os::unix::fs::PermissionsExt::from_mode(0o666);
    let mut tmp = tempfile::Builder::new()
        .prefix(".frond-gltf-")
        .suffix(".tmp")
        .permissions(mode)
        .tempfile_in(dir)
        .map_err(|e| output_err(path, format!("cannot create a file in {}: {e}", dir.display())))?;
    tmp.write_all(bytes).map_err(|e| output_err(path, e.to_string()))?;
    tmp.as_file().sync_all().map_err(|e| output_err(path, e.to_string()))?;
    Ok(tmp)
}

fn persist(tmp: tempfile::NamedTempFile, path: &Path) -> Result<(), BakeError> {
    tmp.persist(path).map_err(|e| output_err(path, e.error.to_string()))?;
    Ok(())
}
