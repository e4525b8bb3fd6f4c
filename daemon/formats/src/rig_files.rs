//! The one place rigs come from, for the daemon, `frond` and every exporter: the rigs built into
//! every binary (`rig-files/plants/`), and rig files, read safely. The only I/O in this crate:
//! it reads one small regular file, and nothing else.
//!
//! A rig argument is a path when it contains `/` or ends in `.toml`; otherwise it names an
//! embedded rig, and if none has that name, a file in the current directory.

use std::io::Read;
use std::path::{Path, PathBuf};

use thiserror::Error;

use frond_motion::rig::{Rig, RigError};

use crate::rig_toml::RigText;

/// The rigs of `rig-files/plants/`, built into every binary: `(name, TOML text)`.
pub const EMBEDDED_RIGS: [(&str, &str); 3] = [
    ("grass", include_str!("../../../rig-files/plants/grass.toml")),
    ("flower", include_str!("../../../rig-files/plants/flower.toml")),
    ("shrub", include_str!("../../../rig-files/plants/shrub.toml")),
];

/// Largest rig (or calibration) file read, bytes; anything larger is refused before reading.
pub const MAX_RIG_FILE_BYTES: u64 = 1 << 20;

/// Why a small text file could not be read.
#[derive(Debug, Error)]
pub enum FileError {
    /// Opening or reading failed.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The path is a FIFO, a device, a directory or a socket.
    #[error("{} is {what}, not a regular file", path.display())]
    NotRegular {
        /// The file.
        path: PathBuf,
        /// What it is instead.
        what: &'static str,
    },
    /// The file is larger than the limit.
    #[error("{} is {bytes} bytes; the limit is {max}", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        max: u64,
    },
    /// The file is not UTF-8 text.
    #[error("{} is not UTF-8 text", path.display())]
    NotText {
        /// The file.
        path: PathBuf,
    },
}

impl FileError {
    /// The file.
    pub fn path(&self) -> &Path {
        match self {
            FileError::Read { path, .. }
            | FileError::NotRegular { path, .. }
            | FileError::TooLarge { path, .. }
            | FileError::NotText { path } => path,
        }
    }

    /// What is wrong, without the path (for messages that name the file themselves).
    pub fn reason(&self) -> String {
        match self {
            FileError::Read { source, .. } => source.to_string(),
            FileError::NotRegular { what, .. } => format!("it is {what}, not a regular file"),
            FileError::TooLarge { bytes, max, .. } => format!("it is {bytes} bytes; the limit is {max}"),
            FileError::NotText { .. } => "it is not UTF-8 text".to_string(),
        }
    }
}

/// Why a rig could not be loaded.
#[derive(Debug, Error)]
pub enum RigFileError {
    /// The argument names no embedded rig and no file.
    #[error("rig `{spec}` not found: not an embedded rig ({embedded}) and no such file")]
    NotFound {
        /// The argument.
        spec: String,
        /// The embedded rigs' names.
        embedded: String,
    },
    /// A name kept by a take (or sent by a daemon) that is not an embedded rig: a rig loaded
    /// from a file keeps only its own name, and a name from a file is never opened as a path.
    #[error(
        "rig {name:?} is not an embedded rig ({embedded}); it was loaded from a file: give that file with --rig FILE"
    )]
    NotEmbedded {
        /// The kept name.
        name: String,
        /// The embedded rigs' names.
        embedded: String,
    },
    /// The file could not be read. (Not a `source`: the message already says it all, and a
    /// chain printed after it would repeat it.)
    #[error("cannot read rig {}: {}", .0.path().display(), .0.reason())]
    File(FileError),
    /// The rig did not validate.
    #[error("{origin}: {source}")]
    Invalid {
        /// `embedded rig grass` or the file path.
        origin: String,
        /// Every problem with its field path.
        #[source]
        source: RigError,
    },
}

impl From<FileError> for RigFileError {
    fn from(e: FileError) -> Self {
        RigFileError::File(e)
    }
}

/// A validated rig, its text and where it came from.
#[derive(Debug, Clone)]
pub struct LoadedRig {
    /// The rig (named after the file stem or the embedded name when it names itself not).
    pub rig: Rig,
    /// Its TOML text (to send to the daemon, which validates it again).
    pub text: String,
    /// `embedded rig grass` or the file path, for messages.
    pub origin: String,
    /// Directory of the rig file (mesh files are relative to it); `None` when embedded.
    pub dir: Option<PathBuf>,
}

/// What a file's type is, in words (`a FIFO`, `a directory`, ...), unless it is a regular file.
pub fn not_regular(ft: std::fs::FileType) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_file() {
        None
    } else if ft.is_dir() {
        Some("a directory")
    } else if ft.is_fifo() {
        Some("a FIFO")
    } else if ft.is_char_device() || ft.is_block_device() {
        Some("a device")
    } else if ft.is_socket() {
        Some("a socket")
    } else {
        Some("not a regular file")
    }
}

/// Where a file given as an output path may be written, checked before anything is: the path
/// itself when it is a regular file or does not exist yet in an existing directory, or the file
/// a symbolic link names when that is a regular file (the link stays, its target is replaced).
/// A device, FIFO, socket or directory there is refused rather than replaced by a regular file
/// (`-o /dev/null` run as root would otherwise swap the device node for a file), as are a
/// dangling link and a missing directory (a typo is not made into a new directory tree).
pub fn output_destination(path: &Path) -> std::io::Result<PathBuf> {
    use std::io::{Error, ErrorKind};
    if path.as_os_str().is_empty() {
        return Err(Error::new(ErrorKind::InvalidInput, "the output path is empty"));
    }
    if path.as_os_str() == "-" {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "`-` (standard output) is not taken here; give a file path (./- for a file named -)",
        ));
    }
    match std::fs::symlink_metadata(path) {
        Ok(link) if link.file_type().is_symlink() => {
            let target = match std::fs::metadata(path) {
                Ok(target) => target,
                Err(e) if e.kind() == ErrorKind::NotFound => {
                    return Err(Error::new(
                        ErrorKind::NotFound,
                        "it is a symbolic link to a file that does not exist; remove the link or name the file itself",
                    ));
                }
                Err(e) => return Err(e),
            };
            if let Some(what) = not_regular(target.file_type()) {
                return Err(Error::new(
                    ErrorKind::InvalidInput,
                    format!("it is a symbolic link to {what}, not to a regular file"),
                ));
            }
            if !may_follow(path, &link) {
                return Err(Error::new(
                    ErrorKind::PermissionDenied,
                    "it is a symbolic link that another user made in a shared directory (sticky and \
                     world-writable, as /tmp); it is not followed: name the file itself",
                ));
            }
            std::fs::canonicalize(path)
        }
        Ok(meta) => match not_regular(meta.file_type()) {
            None => Ok(path.to_path_buf()),
            Some(what) => {
                Err(Error::new(ErrorKind::InvalidInput, format!("it is {what}, not a regular file")))
            }
        },
        Err(e) if e.kind() == ErrorKind::NotFound => {
            let dir = parent_dir(path);
            if dir.is_dir() {
                Ok(path.to_path_buf())
            } else {
                Err(Error::new(
                    ErrorKind::NotFound,
                    format!("the directory {} does not exist", dir.display()),
                ))
            }
        }
        Err(e) => Err(e),
    }
}

/// Whether writing through the symbolic link `path` (its own metadata `link`) is safe: Linux's
/// `fs.protected_symlinks` rule, which following the link ourselves would bypass. In a sticky,
/// world-writable directory (`/tmp`) only a link owned by this user or by the directory's owner
/// is followed; elsewhere any link is. Otherwise a user could plant `/tmp/x.bvh ->
/// /etc/shadow` for root's `-o /tmp/x.bvh` to replace.
fn may_follow(path: &Path, link: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    let dir = parent_dir(path);
    let Ok(dir) = std::fs::metadata(dir) else { return false };
    let shared = dir.mode() & 0o1002 == 0o1002;
    // SAFETY: geteuid has no preconditions and cannot fail.
    let me = unsafe { libc::geteuid() };
    !shared || link.uid() == me || link.uid() == dir.uid()
}

/// The directory `path` is in: its parent, or `.` for a bare file name.
pub fn parent_dir(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// A file being written in place of an output path: a temporary file beside the destination,
/// renamed over it by [`AtomicOutput::persist`] once synced, so readers (and a crash) see the old
/// file or the whole new one, and one dropped unpersisted (a failed render) leaves nothing. A
/// replaced file's permissions are kept; a new file gets what any new file gets (0666 less the
/// umask), not a temporary file's private 0600: an export is meant to be read by other tools
/// and users. Only where [`output_destination`] allows: never over a device, FIFO or
/// directory, through a symbolic link to its regular file, and into a directory that exists.
/// The one way frond writes a file it is given ([`write_file_atomically`] for bytes in
/// memory; this for output streamed to disk, such as a GIF too large to hold).
pub struct AtomicOutput {
    tmp: tempfile::NamedTempFile,
    dest: PathBuf,
}

impl AtomicOutput {
    /// Checks `path` and creates the temporary file beside the file it names.
    pub fn create(path: &Path) -> std::io::Result<AtomicOutput> {
        let dest = output_destination(path)?;
        let dir = parent_dir(&dest);
        let tmp = match std::fs::metadata(&dest) {
            Ok(meta) => {
                let tmp = tempfile::NamedTempFile::new_in(dir)?;
                tmp.as_file().set_permissions(meta.permissions())?;
                tmp
            }
            Err(_) => {
                use std::os::unix::fs::PermissionsExt;
                tempfile::Builder::new()
                    .permissions(std::fs::Permissions::from_mode(0o666))
                    .tempfile_in(dir)?
            }
        };
        Ok(AtomicOutput { tmp, dest })
    }

    /// The temporary file, to write to (or to clone a handle of for a writer that owns one).
    pub fn file(&mut self) -> &mut std::fs::File {
        self.tmp.as_file_mut()
    }

    /// Syncs what was written to disk and renames it over the destination.
    pub fn persist(self) -> std::io::Result<()> {
        self.tmp.as_file().sync_all()?;
        self.tmp.persist(&self.dest).map(|_| ()).map_err(|e| e.error)
    }
}

/// Writes `bytes` to `path` through an [`AtomicOutput`]: the old file or the whole new one,
/// never over a device, FIFO or directory.
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = AtomicOutput::create(path)?;
    out.file().write_all(bytes)?;
    out.persist()
}

/// Reads a small regular text file: [`read_small_file`], then UTF-8.
pub fn read_small_text(path: &Path, max: u64) -> Result<String, FileError> {
    let bytes = read_small_file(path, max)?;
    String::from_utf8(bytes).map_err(|_| FileError::NotText { path: path.to_path_buf() })
}

/// Reads a regular file of at most `max` bytes: refuses FIFOs, devices and directories without
/// blocking on them (the file is opened non-blocking and checked before anything is read), and
/// files over `max` bytes before reading them (and if one grows past `max` while read). The
/// one way every frond command and the daemon read a file they are given.
pub fn read_small_file(path: &Path, max: u64) -> Result<Vec<u8>, FileError> {
    use std::os::unix::fs::OpenOptionsExt;
    let read_err = |source| FileError::Read { path: path.to_path_buf(), source };
    if let Ok(meta) = std::fs::metadata(path)
        && let Some(what) = not_regular(meta.file_type())
    {
        return Err(FileError::NotRegular { path: path.to_path_buf(), what });
    }
    // O_NONBLOCK: a FIFO swapped in after the check still cannot block the open.
    let file =
        std::fs::OpenOptions::new().read(true).custom_flags(O_NONBLOCK).open(path).map_err(read_err)?;
    let meta = file.metadata().map_err(read_err)?;
    if let Some(what) = not_regular(meta.file_type()) {
        return Err(FileError::NotRegular { path: path.to_path_buf(), what });
    }
    if meta.len() > max {
        return Err(FileError::TooLarge { path: path.to_path_buf(), bytes: meta.len(), max });
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(max + 1).read_to_end(&mut bytes).map_err(read_err)?;
    if bytes.len() as u64 > max {
        return Err(FileError::TooLarge { path: path.to_path_buf(), bytes: bytes.len() as u64, max });
    }
    Ok(bytes)
}

/// Largest take file a command reads, bytes: about 16 million frames, the resampling limit
/// ([`frond_motion::take::MAX_RESAMPLED_FRAMES`]).
pub const MAX_TAKE_FILE_BYTES: u64 = 2 << 30;
/// Largest mesh file (`.glb`) a rig may name, bytes.
pub const MAX_MESH_FILE_BYTES: u64 = 256 << 20;

/// Reads a take file: [`read_small_file`] with [`MAX_TAKE_FILE_BYTES`].
pub fn read_take_file(path: &Path) -> Result<Vec<u8>, FileError> {
    read_small_file(path, MAX_TAKE_FILE_BYTES)
}

/// `O_NONBLOCK` on Linux (every architecture frond builds for).
const O_NONBLOCK: i32 = 0o4000;

/// Parses a rig's TOML text; `origin` names it in errors, `default_name` names it when the file
/// does not.
pub fn rig_from_text(
    text: String,
    origin: String,
    default_name: &str,
    dir: Option<PathBuf>,
) -> Result<LoadedRig, RigFileError> {
    let mut rig = Rig::from_toml_str(&text)
        .map_err(|source| RigFileError::Invalid { origin: origin.clone(), source })?;
    if rig.name.is_empty() {
        rig.name = default_name.to_string();
    }
    Ok(LoadedRig { rig, text, origin, dir })
}

/// The embedded rig `name`, if there is one.
pub fn embedded_rig(name: &str) -> Option<Result<LoadedRig, RigFileError>> {
    EMBEDDED_RIGS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(n, text)| rig_from_text(text.to_string(), format!("embedded rig `{n}`"), n, None))
}

/// A rig file.
pub fn rig_file(path: &Path) -> Result<LoadedRig, RigFileError> {
    let text = read_small_text(path, MAX_RIG_FILE_BYTES)?;
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let dir =
        path.parent().map(|d| if d.as_os_str().is_empty() { PathBuf::from(".") } else { d.to_path_buf() });
    rig_from_text(text, path.display().to_string(), &stem, dir)
}

/// Loads a rig argument: a path (contains `/` or ends in `.toml`), else an embedded rig name,
/// else a file of that name.
pub fn load_rig(spec: &str) -> Result<LoadedRig, RigFileError> {
    let looks_like_path = spec.contains('/') || spec.ends_with(".toml");
    if !looks_like_path && let Some(r) = embedded_rig(spec) {
        return r;
    }
    let path = Path::new(spec);
    if !looks_like_path && std::fs::symlink_metadata(path).is_err() {
        return Err(RigFileError::NotFound {
            spec: spec.to_string(),
            embedded: EMBEDDED_RIGS.map(|(n, _)| n).join(", "),
        });
    }
    rig_file(path)
}

/// The rig a take was recorded on (or a daemon reports), by the name it keeps: an embedded rig
/// only. Unlike [`load_rig`], never opens a path: the name comes from a file or a peer, and a
/// take must not make frond read `/dev/zero` or `/etc/shadow`.
pub fn recorded_rig(name: &str) -> Result<LoadedRig, RigFileError> {
    embedded_rig(name).unwrap_or_else(|| {
        Err(RigFileError::NotEmbedded {
            name: name.to_string(),
            embedded: EMBEDDED_RIGS.map(|(n, _)| n).join(", "),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_writes_give_new_files_the_usual_mode_and_keep_a_replaced_ones() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        // The mode any new file gets here (0666 less the umask), made the ordinary way.
        let plain = dir.path().join("plain");
        std::fs::write(&plain, b"x").unwrap();
        let new = dir.path().join("new.bvh");
        write_file_atomically(&new, b"one").unwrap();
        assert_eq!(mode(&new), mode(&plain));
        std::fs::set_permissions(&new, std::fs::Permissions::from_mode(0o640)).unwrap();
        write_file_atomically(&new, b"two").unwrap();
        assert_eq!((mode(&new), std::fs::read(&new).unwrap()), (0o640, b"two".to_vec()));
    }

    #[test]
    fn atomic_writes_refuse_what_is_not_a_regular_file_and_write_through_a_link() {
        use std::os::unix::fs::{FileTypeExt, symlink};
        let dir = tempfile::tempdir().unwrap();
        let at = |name: &str| dir.path().join(name);
        let err = |path: &Path| write_file_atomically(path, b"x").unwrap_err().to_string();

        // A FIFO stays a FIFO (made with mkfifo(1), as a user would).
        let fifo = at("fifo");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        assert_eq!(err(&fifo), "it is a FIFO, not a regular file");
        assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());

        // A device node (a link to /dev/null stands for it: no mknod needed) and a directory.
        symlink("/dev/null", at("null")).unwrap();
        assert_eq!(err(&at("null")), "it is a symbolic link to a device, not to a regular file");
        assert_eq!(std::fs::read_link(at("null")).unwrap(), Path::new("/dev/null"));
        std::fs::create_dir(at("d")).unwrap();
        assert_eq!(err(&at("d")), "it is a directory, not a regular file");

        // A missing directory is not created; a dangling link is refused.
        assert_eq!(
            err(&at("no/such/x.bvh")),
            format!("the directory {} does not exist", at("no/such").display())
        );
        assert!(!at("no").exists());
        symlink(at("gone"), at("dangling")).unwrap();
        assert!(err(&at("dangling")).starts_with("it is a symbolic link to a file that does not exist"));
        assert!(!at("gone").exists());

        // A link to a regular file: the target gets the bytes, the link stays a link.
        std::fs::write(at("target.glb"), b"old").unwrap();
        symlink(at("target.glb"), at("link.glb")).unwrap();
        write_file_atomically(&at("link.glb"), b"new").unwrap();
        assert!(std::fs::symlink_metadata(at("link.glb")).unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read(at("target.glb")).unwrap(), b"new");
        assert_eq!(err(Path::new("")), "the output path is empty");
        assert!(err(Path::new("-")).starts_with("`-` (standard output) is not taken here"));
    }

    #[test]
    fn a_link_another_user_planted_in_a_shared_directory_is_not_followed() {
        use std::os::unix::fs::{PermissionsExt, lchown, symlink};
        // A /tmp of our own: sticky and world-writable, owned by us; the link is made by user
        // 4242 (needs root to give it away, as the tests run; otherwise there is nothing to test).
        let dir = tempfile::tempdir().unwrap();
        let shared = dir.path().join("shared");
        std::fs::create_dir(&shared).unwrap();
        std::fs::set_permissions(&shared, std::fs::Permissions::from_mode(0o1777)).unwrap();
        let secret = dir.path().join("secret");
        std::fs::write(&secret, b"keep").unwrap();
        let planted = shared.join("x.bvh");
        symlink(&secret, &planted).unwrap();
        if lchown(&planted, Some(4242), None).is_err() {
            return;
        }
        let e = write_file_atomically(&planted, b"new").unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied, "{e}");
        assert_eq!(std::fs::read(&secret).unwrap(), b"keep");
        // Our own link there is followed; a planted one outside a shared directory too.
        // SAFETY: geteuid has no preconditions and cannot fail.
        let me = unsafe { libc::geteuid() };
        lchown(&planted, Some(me), None).unwrap();
        write_file_atomically(&planted, b"ours").unwrap();
        assert_eq!(std::fs::read(&secret).unwrap(), b"ours");
    }

    #[test]
    fn a_recorded_rig_name_is_an_embedded_rig_or_refused_never_a_path() {
        assert_eq!(recorded_rig("grass").unwrap().rig.name, load_rig("grass").unwrap().rig.name);
        for name in ["/dev/zero", "my-shrub", "grass.toml", "../grass", ""] {
            let e = recorded_rig(name).unwrap_err().to_string();
            assert!(e.starts_with(&format!("rig {name:?} is not an embedded rig (grass, ")), "{e}");
            assert!(e.ends_with("give that file with --rig FILE"), "{e}");
        }
    }

    #[test]
    fn embedded_rigs_load_by_name_and_name_themselves() {
        for (name, _) in EMBEDDED_RIGS {
            let r = load_rig(name).unwrap();
            assert!(!r.rig.name.is_empty());
            assert!(r.origin.contains(name) && r.dir.is_none());
        }
        let e = load_rig("fern").unwrap_err();
        assert_eq!(
            e.to_string(),
            "rig `fern` not found: not an embedded rig (grass, flower, shrub) and no such file"
        );
        let e = load_rig("/no/such/rig.toml").unwrap_err();
        assert!(e.to_string().starts_with("cannot read rig /no/such/rig.toml: "), "{e}");
    }

    #[test]
    fn files_load_and_bad_ones_are_refused_by_kind() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("mine.toml");
        std::fs::write(&good, EMBEDDED_RIGS[0].1).unwrap();
        let r = load_rig(good.to_str().unwrap()).unwrap();
        assert_eq!(r.dir.as_deref(), Some(dir.path()));
        // A directory, a FIFO (refused without blocking), /dev/zero, an oversized file.
        assert!(matches!(
            rig_file(dir.path()),
            Err(RigFileError::File(FileError::NotRegular { what: "a directory", .. }))
        ));
        let fifo = dir.path().join("fifo.toml");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        assert!(matches!(
            rig_file(&fifo),
            Err(RigFileError::File(FileError::NotRegular { what: "a FIFO", .. }))
        ));
        assert!(matches!(
            rig_file(Path::new("/dev/zero")),
            Err(RigFileError::File(FileError::NotRegular { what: "a device", .. }))
        ));
        let big = dir.path().join("big.toml");
        std::fs::File::create(&big).unwrap().set_len(MAX_RIG_FILE_BYTES + 1).unwrap();
        assert!(matches!(rig_file(&big), Err(RigFileError::File(FileError::TooLarge { .. }))));
        let bad = dir.path().join("bad.toml");
        std::fs::write(&bad, "name = 3").unwrap();
        let e = rig_file(&bad).unwrap_err();
        assert!(matches!(e, RigFileError::Invalid { .. }) && e.to_string().contains("bad.toml"), "{e}");
    }
}

/// Why a rig's plant geometry could not be built.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("rig {origin}: mesh: {reason}")]
pub struct PlantModelError {
    /// The rig (`embedded rig grass` or its file).
    pub origin: String,
    /// What is wrong.
    pub reason: String,
}

/// The plant geometry of a loaded rig: the procedural shape its `[mesh]` names, or its
/// glTF/GLB mesh file (read relative to the rig file, at most [`MAX_MESH_FILE_BYTES`], skin
/// weights from the file where it has them). The one loader for every exporter.
pub fn plant_model(loaded: &LoadedRig) -> Result<frond_motion::mesh::PlantModel, PlantModelError> {
    use frond_motion::rig::MeshSpec;
    let err = |reason: String| PlantModelError { origin: loaded.origin.clone(), reason };
    match &loaded.rig.mesh {
        MeshSpec::Procedural { .. } => {
            frond_motion::mesh::procedural_model(&loaded.rig).map_err(|e| err(e.to_string()))
        }
        MeshSpec::File { path } => {
            let full = match &loaded.dir {
                Some(dir) => dir.join(path),
                None => PathBuf::from(path),
            };
            let bytes = read_small_file(&full, MAX_MESH_FILE_BYTES)
                .map_err(|e| err(format!("cannot read {}: {}", full.display(), e.reason())))?;
            let skeleton = frond_motion::skeleton::Skeleton::from_rig(&loaded.rig);
            let names: Vec<String> = loaded.rig.joints.iter().map(|j| j.name.clone()).collect();
            let stem = crate::gltf_mesh::load_gltf_mesh(&bytes, &skeleton, &names)
                .map_err(|e| err(format!("{}: {e}", full.display())))?;
            Ok(frond_motion::mesh::PlantModel { skeleton, stem, elements: Vec::new() })
        }
    }
}
