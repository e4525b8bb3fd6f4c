//! Where frond's sockets and takes live, resolved the same way by the daemon, the CLI and the SDK.
//!
//! Order: explicit argument, then the environment variable (`FROND_SOCKET_DIR`,
//! `FROND_TAKES_DIR`), then the XDG directory, then a fallback that works without XDG.

use std::path::{Path, PathBuf};

/// Environment variable naming the socket directory.
pub const SOCKET_DIR_ENV: &str = "FROND_SOCKET_DIR";
/// Environment variable naming the takes directory.
pub const TAKES_DIR_ENV: &str = "FROND_TAKES_DIR";

/// `--socket-dir`'s help in every program: where the directory is when the option is not given
/// ([`default_socket_dir`]).
pub const SOCKET_DIR_HELP: &str = "Directory of the daemon's sockets (poses.sock, control.sock) \
     [default: $FROND_SOCKET_DIR, else $XDG_RUNTIME_DIR/frond, else /run/frond for root, else /tmp/frond-UID]";

/// `--takes-dir`'s help in every program ([`default_takes_dir`]).
pub const TAKES_DIR_HELP: &str = "Directory of recorded takes [default: $FROND_TAKES_DIR, else \
     $XDG_DATA_HOME/frond/takes, else ~/.local/share/frond/takes, else /var/lib/frond/takes]";

fn env_dir(name: &str) -> Option<PathBuf> {
    std::env::var_os(name).filter(|v| !v.is_empty()).map(PathBuf::from)
}

fn uid() -> u32 {
    // Avoids a libc dependency in the protocol crate: /proc/self is owned by our uid.
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata("/proc/self").map(|m| m.uid()).unwrap_or(0)
}

/// The socket directory: `$FROND_SOCKET_DIR`, else `$XDG_RUNTIME_DIR/frond`, else
/// `/run/frond` for root, else `/tmp/frond-<uid>`.
pub fn default_socket_dir() -> PathBuf {
    if let Some(dir) = env_dir(SOCKET_DIR_ENV) {
        return dir;
    }
    if let Some(xdg) = env_dir("XDG_RUNTIME_DIR") {
        return xdg.join("frond");
    }
    match uid() {
        0 => PathBuf::from("/run/frond"),
        uid => PathBuf::from(format!("/tmp/frond-{uid}")),
    }
}

/// The takes directory: `$FROND_TAKES_DIR`, else `$XDG_DATA_HOME/frond/takes`, else
/// `$HOME/.local/share/frond/takes`, else `/var/lib/frond/takes`.
pub fn default_takes_dir() -> PathBuf {
    if let Some(dir) = env_dir(TAKES_DIR_ENV) {
        return dir;
    }
    if let Some(xdg) = env_dir("XDG_DATA_HOME") {
        return xdg.join("frond").join("takes");
    }
    if let Some(home) = env_dir("HOME") {
        return home.join(".local/share/frond/takes");
    }
    PathBuf::from("/var/lib/frond/takes")
}

/// Resolves an optional explicit socket directory.
pub fn socket_dir(explicit: Option<PathBuf>) -> PathBuf {
    explicit.unwrap_or_else(default_socket_dir)
}

/// Resolves an optional explicit takes directory.
pub fn takes_dir(explicit: Option<PathBuf>) -> PathBuf {
    explicit.unwrap_or_else(default_takes_dir)
}

/// The file name of camera `n`'s preview picture in the socket directory (`webcam-N.jpg`): the
/// landmark helper keeps it, the console serves it to its page.
pub fn camera_preview_name(n: u32) -> String {
    format!("webcam-{n}.jpg")
}

/// Whether `name` is a name [`camera_preview_name`] gives (`webcam-` and 1 to 10 digits, then
/// `.jpg`): the one check before a name from a status report or a request is joined to the
/// socket directory, so it can never name another file there or leave it.
pub fn is_camera_preview_name(name: &str) -> bool {
    name.strip_prefix("webcam-")
        .and_then(|r| r.strip_suffix(".jpg"))
        .is_some_and(|n| (1..=10).contains(&n.len()) && n.bytes().all(|b| b.is_ascii_digit()))
}

/// Why a take name is refused ([`validate_take_name`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TakeNameError {
    /// Empty or longer than 128 bytes; the length found.
    #[error("take name must be 1 to 128 characters, got {0}")]
    Length(usize),
    /// Starts with `.` (hidden, or `..`).
    #[error("take name {0:?} must not start with '.'")]
    LeadingDot(String),
    /// Holds a character other than ASCII letters, digits, `-`, `_` and `.`.
    #[error("take name {name:?} contains {found:?}; use letters, digits, '-', '_' and '.' only")]
    Character {
        /// The name.
        name: String,
        /// The first character refused.
        found: char,
    },
}

/// Checks a take name: 1-128 bytes of ASCII letters, digits, `-`, `_`, `.`, not starting with
/// `.`, so a name can never escape the takes directory (`../`, `/`, NUL are all refused).
pub fn validate_take_name(name: &str) -> Result<(), TakeNameError> {
    if name.is_empty() || name.len() > 128 {
        return Err(TakeNameError::Length(name.len()));
    }
    if name.starts_with('.') {
        return Err(TakeNameError::LeadingDot(name.into()));
    }
    if let Some(found) = name.chars().find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))) {
        return Err(TakeNameError::Character { name: name.into(), found });
    }
    Ok(())
}

/// Where a take argument points: the one rule of every binary that takes a take (`frond take
/// export NAME`, `frond-gltf bake --take`, `frond-warp render --take`, ...). An argument with a
/// `/`, ending in `.take`, or naming a file that exists is that file; anything else is a take
/// name (checked by [`validate_take_name`]), the file `NAME.take` in `takes_dir` (the
/// `--takes-dir`, else [`takes_dir`]'s default).
pub fn take_file(arg: &str, takes_dir: &Path) -> Result<PathBuf, TakeNameError> {
    let path = Path::new(arg);
    if arg.contains('/') || arg.ends_with(".take") || path.is_file() {
        return Ok(path.to_path_buf());
    }
    validate_take_name(arg)?;
    Ok(takes_dir.join(format!("{arg}.take")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_directory_helps_name_every_place_the_defaults_look() {
        for place in ["$FROND_SOCKET_DIR", "$XDG_RUNTIME_DIR/frond", "/run/frond for root", "/tmp/frond-UID"]
        {
            assert!(SOCKET_DIR_HELP.contains(place), "{place}");
        }
        let takes = [
            "$FROND_TAKES_DIR",
            "$XDG_DATA_HOME/frond/takes",
            "~/.local/share/frond/takes",
            "/var/lib/frond/takes",
        ];
        for place in takes {
            assert!(TAKES_DIR_HELP.contains(place), "{place}");
        }
    }

    #[test]
    fn a_take_argument_is_a_path_or_a_name_in_the_takes_directory() {
        let dir = Path::new("/srv/takes");
        assert_eq!(take_file("t1", dir).unwrap(), Path::new("/srv/takes/t1.take"));
        assert_eq!(take_file("a.b-c_d", dir).unwrap(), Path::new("/srv/takes/a.b-c_d.take"));
        assert_eq!(take_file("./t1", dir).unwrap(), Path::new("./t1"));
        assert_eq!(take_file("/x/t1.take", dir).unwrap(), Path::new("/x/t1.take"));
        assert_eq!(take_file("t1.take", dir).unwrap(), Path::new("t1.take"));
        assert!(matches!(take_file("..", dir), Err(TakeNameError::LeadingDot(_))));
        assert!(matches!(take_file("a b", dir), Err(TakeNameError::Character { .. })));
        assert!(matches!(take_file("", dir), Err(TakeNameError::Length(0))));
    }

    #[test]
    fn camera_preview_names_are_only_their_own() {
        assert_eq!(camera_preview_name(3), "webcam-3.jpg");
        assert!(is_camera_preview_name(&camera_preview_name(u32::MAX)));
        for bad in [
            "webcam-.jpg",
            "webcam-1.png",
            "webcam-../x.jpg",
            "x/webcam-1.jpg",
            "webcam-1.jpg/",
            "webcam-12345678901.jpg",
            "webcam-+1.jpg",
            "control.sock",
            "",
        ] {
            assert!(!is_camera_preview_name(bad), "{bad:?}");
        }
    }

    #[test]
    fn take_names_cannot_escape() {
        for bad in ["", "../x", "/etc/passwd", "a/b", ".hidden", "a\0b", "..", "é"] {
            assert!(validate_take_name(bad).is_err(), "{bad:?} accepted");
        }
        for good in ["take1", "wind-gust_02", "a.b"] {
            assert!(validate_take_name(good).is_ok(), "{good:?} refused");
        }
        assert_eq!(validate_take_name(""), Err(TakeNameError::Length(0)));
        assert_eq!(validate_take_name(&"a".repeat(129)), Err(TakeNameError::Length(129)));
        assert_eq!(
            validate_take_name("../x").unwrap_err().to_string(),
            r#"take name "../x" must not start with '.'"#
        );
        assert_eq!(
            validate_take_name("a/b").unwrap_err().to_string(),
            r#"take name "a/b" contains '/'; use letters, digits, '-', '_' and '.' only"#
        );
    }
}
