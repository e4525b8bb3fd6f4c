//! How rendered frames reach the disk: the GIF encoder's writer (into a
//! `frond_formats::rig_files::AtomicOutput`), and the directory of PNG frames checked and made.

use std::io::Write;
use std::path::Path;

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
                frond_formats::rig_files::not_regular(meta.file_type()).unwrap_or("a regular file")
            ),
        )),
        Err(e) if e.kind() == ErrorKind::NotFound => {
            if std::fs::symlink_metadata(path).is_ok() {
                return Err(Error::new(
                    ErrorKind::NotFound,
                    "it is a symbolic link to a directory that does not exist; remove the link or name the directory itself",
                ));
            }
            let dir = frond_formats::rig_files::parent_dir(path);
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
