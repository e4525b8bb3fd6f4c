//! The Zenoh session's configuration, built alike by the bridge and the subscribers: a
//! configuration file read with bounds, endpoints and extra keys on top, and `ZENOH_RUNTIME`
//! checked before Zenoh reads it. Re-exported from [`crate::zenoh`].

use std::io::Read;
use std::path::Path;

use ::zenoh::Wait;

/// Largest Zenoh configuration file read, bytes.
pub const MAX_CONFIG_FILE: u64 = 256 * 1024;

/// Why a Zenoh session could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum ZenohSetupError {
    /// The configuration file could not be read or is not a small regular file.
    #[error("Zenoh configuration {}: {why}", path.display())]
    ConfigFile {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong.
        why: String,
    },
    /// Zenoh refused the configuration or could not open the session.
    #[error("Zenoh: {0}")]
    Zenoh(String),
    /// `ZENOH_RUNTIME` holds a value Zenoh cannot use (see [`crate::zenoh_runtime_env`]).
    #[error(transparent)]
    RuntimeEnv(#[from] crate::zenoh_runtime_env::RuntimeEnvError),
}

/// Builds a Zenoh configuration: the file (if any, checked to be a regular file of at most
/// [`MAX_CONFIG_FILE`] bytes), then `mode`, the endpoints to connect to and listen on, and
/// `extra` key/JSON5-value pairs (e.g. `("timestamping/enabled", "true")`).
pub fn config(
    file: Option<&Path>,
    mode: Option<&str>,
    connect: &[String],
    listen: &[String],
    extra: &[(&str, &str)],
) -> Result<::zenoh::Config, ZenohSetupError> {
    let mut config = match file {
        Some(path) => {
            let bad = |why: String| ZenohSetupError::ConfigFile { path: path.to_owned(), why };
            let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
            let meta = file.metadata().map_err(|e| bad(e.to_string()))?;
            if !meta.is_file() {
                return Err(bad("not a regular file".into()));
            }
            if meta.len() > MAX_CONFIG_FILE {
                return Err(bad(format!("{} bytes; at most {MAX_CONFIG_FILE}", meta.len())));
            }
            let mut text = String::new();
            file.take(MAX_CONFIG_FILE).read_to_string(&mut text).map_err(|e| bad(e.to_string()))?;
            ::zenoh::Config::from_json5(&text).map_err(|e| bad(e.to_string()))?
        }
        None => ::zenoh::Config::default(),
    };
    let set = |config: &mut ::zenoh::Config, key: &str, value: &str| {
        config.insert_json5(key, value).map_err(|e| ZenohSetupError::Zenoh(format!("{key} = {value}: {e}")))
    };
    if let Some(mode) = mode {
        set(&mut config, "mode", &json_string(mode))?;
    }
    if !connect.is_empty() {
        set(&mut config, "connect/endpoints", &json_list(connect))?;
    }
    if !listen.is_empty() {
        set(&mut config, "listen/endpoints", &json_list(listen))?;
    }
    for (key, value) in extra {
        set(&mut config, key, value)?;
    }
    Ok(config)
}

fn json_string(s: &str) -> String {
    serde_json::Value::String(s.to_owned()).to_string()
}

fn json_list(items: &[String]) -> String {
    serde_json::Value::Array(items.iter().map(|s| serde_json::Value::String(s.clone())).collect()).to_string()
}

/// Opens a session with what a `zenoh:` address says after its `?`: its configuration file and
/// its `connect` and `listen` endpoints ([`config`], [`open_session`]). Every subscription,
/// status query and remote control of one address opens its session so.
pub fn open_addr_session(addr: &crate::ZenohAddr) -> Result<::zenoh::Session, ZenohSetupError> {
    open_session(config(addr.config.as_deref(), None, &addr.connect, &addr.listen, &[])?)
}

/// Opens a session with [`config`], after checking `ZENOH_RUNTIME` (on which Zenoh panics).
pub fn open_session(config: ::zenoh::Config) -> Result<::zenoh::Session, ZenohSetupError> {
    crate::zenoh_runtime_env::check()?;
    ::zenoh::open(config).wait().map_err(|e| ZenohSetupError::Zenoh(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn configs_take_endpoints_and_refuse_odd_files() {
        let c = config(
            None,
            Some("peer"),
            &["tcp/127.0.0.1:7447".into()],
            &[],
            &[("timestamping/enabled", "true")],
        );
        assert!(c.is_ok());
        let dir = tempfile::tempdir().unwrap();
        let err = config(Some(dir.path()), None, &[], &[], &[]).unwrap_err().to_string();
        assert!(err.contains("not a regular file"), "{err}");
        let big = dir.path().join("big.json5");
        std::fs::write(&big, vec![b' '; MAX_CONFIG_FILE as usize + 1]).unwrap();
        assert!(config(Some(&big), None, &[], &[], &[]).unwrap_err().to_string().contains("at most"));
        let bad = dir.path().join("bad.json5");
        std::fs::write(&bad, "{ mode: 42 }").unwrap();
        assert!(config(Some(&bad), None, &[], &[], &[]).is_err());
        let err = config(None, None, &["not an endpoint".into()], &[], &[]).unwrap_err().to_string();
        assert!(err.contains("connect/endpoints"), "{err}");
    }
}
