//! How rendered frames reach the disk: a file through a temporary file renamed into place, the
//! GIF encoder's writer, and the directory of PNG frames checked and made.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Checks the directory of frames `path` (and with `create`, makes it): an existing directory
/// (or a link to one), or a new directory whose parent exists; only the leaf is created.
pub(crate) fn frames_dir(path: &Path, create: bool) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind};
    // `frames/` as `frames`: a trailing slash only says a directory is meant.
    let path = path.components().as_path();
    match std::fs::metadata(path) {
        Ok(meta) if meta.is_dir() => Ok(()),
        Ok(meta) => Err(Error::new(
            ErrorKind::InvalidInput,
            format!(
                "it is {}, not a directory",
                frond_motion::rig_files::not_regular(meta.file_type()).unwrap_or("a regular file")
            ),
        )),
        Err(e) if e.kind() == ErrorKind::NotFound => {
            if std::fs::symlink_metadata(path).is_ok() {
                return Err(Error::new(
                    ErrorKind::NotFound,
                    "it is a symbolic link to a directory that does not exist; remove the link or name the directory itself",
                ));
            }
            let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            if !dir.is_dir() {
                return Err(Error::new(
                    ErrorKind::NotFound,
                    format!("the directory {} does not exist", dir.display()),
                ));
            }
            if create {
                match std::fs::create_dir(path) {
                    Err(e) if e.kind() == ErrorKind::AlreadyExists && path.is_dir() => Ok(()),
                    r => r,
                }
            } else {
                Ok(())
            }
        }
        Err(e) => Err(e),
    }
}

/// A file written through a temporary file beside it, renamed over the destination only when
/// [`AtomicFile::persist`] is called: a render that fails (or is killed) leaves no partial file,
/// and readers see the old file or the whole new one. The temporary file is removed if it is
/// dropped unpersisted. (The streaming form of
/// [`frond_motion::rig_files::write_file_atomically`], for a GIF too large to hold in memory.)
pub(crate) struct AtomicFile {
    dest: PathBuf,
    /// Empty once persisted.
    tmp: PathBuf,
}

impl AtomicFile {
    /// A temporary file in `path`'s directory and the file to write it through, `path` checked
    /// first ([`frond_motion::rig_files::output_destination`]; a link to a regular file is
    /// written through: its target is replaced). A replaced file's permissions are kept; a new
    /// file gets what any new file gets (0666 less the umask).
    pub(crate) fn create(path: &Path) -> std::io::Result<(AtomicFile, std::fs::File)> {
        use std::os::unix::fs::OpenOptionsExt;
        let dest = frond_motion::rig_files::output_destination(path)?;
        let dir = dest.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let name = dest.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let kept = std::fs::metadata(&dest).ok().map(|m| m.permissions());
        static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let mut tries = 0;
        loop {
            let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let tmp = dir.join(format!(".{name}.{}-{n}.tmp", std::process::id()));
            match std::fs::OpenOptions::new().write(true).create_new(true).mode(0o666).open(&tmp) {
                Ok(file) => {
                    let me = AtomicFile { dest, tmp };
                    if let Some(perms) = kept {
                        file.set_permissions(perms)?;
                    }
                    return Ok((me, file));
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && tries < 100 => tries += 1,
                Err(e) => return Err(e),
            }
        }
    }

    /// Flushes `file` (this temporary file) to disk and renames it over the destination.
    pub(crate) fn persist(mut self, file: std::fs::File) -> std::io::Result<()> {
        file.sync_all()?;
        drop(file);
        std::fs::rename(&self.tmp, &self.dest)?;
        self.tmp = PathBuf::new();
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// The GIF encoder's writer: the temporary file, buffered and shared, so that
/// `Sink::finish` gets it back (the encoder keeps its writer, and writes the GIF trailer when
/// dropped), and the first write error kept (the encoder's drop discards the trailer's).
#[derive(Clone)]
pub(crate) struct GifWriter(std::rc::Rc<std::cell::RefCell<GifOut>>);

pub(crate) struct GifOut {
    out: std::io::BufWriter<std::fs::File>,
    failed: Option<std::io::Error>,
}

impl GifWriter {
    pub(crate) fn new(file: std::fs::File) -> GifWriter {
        GifWriter(std::rc::Rc::new(std::cell::RefCell::new(GifOut {
            out: std::io::BufWriter::new(file),
            failed: None,
        })))
    }

    /// The file, everything written to it; the first error of any write.
    pub(crate) fn finish(self) -> std::io::Result<std::fs::File> {
        let cell = std::rc::Rc::try_unwrap(self.0)
            .map_err(|_| std::io::Error::other("the GIF encoder still holds its writer"))?;
        let GifOut { out, failed } = cell.into_inner();
        if let Some(e) = failed {
            return Err(e);
        }
        out.into_inner().map_err(|e| e.into_error())
    }
}

impl Write for GifWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut g = self.0.borrow_mut();
        let r = g.out.write(buf);
        if let Err(e) = &r
            && g.failed.is_none()
        {
            g.failed = Some(std::io::Error::new(e.kind(), e.to_string()));
        }
        r
    }
    fn flush(&mut self) -> std::io::Result<()> {
        let mut g = self.0.borrow_mut();
        let r = g.out.flush();
        if let Err(e) = &r
            && g.failed.is_none()
        {
            g.failed = Some(std::io::Error::new(e.kind(), e.to_string()));
        }
        r
    }
}
