//! Signed control requests for remote control over Zenoh (`frond/<stage>/<source>/control`).
//!
//! Zenoh authenticates *sessions* (user/password, mutual TLS) but does not tell an application
//! which authenticated peer sent a given query: a query's source info is whatever the querier
//! wrote. So every remote control request carries its own proof, an [`Envelope`] in the query's
//! attachment: the principal's name, when it was issued, a random nonce and an HMAC-SHA256 over
//! all of that, the key expression it is addressed to and the request frame, under the
//! principal's shared key. The bridge checks the MAC against its allow-list file, refuses
//! requests issued more than [`MAX_REQUEST_AGE`] before its clock or more than
//! [`MAX_CLOCK_SKEW`] after it ([`check_issue_time`]), and refuses a nonce it has already
//! accepted (replay). Zenoh's own authentication still decides who joins the bus at all.
//!
//! Keys are secrets: a key file, and the bridge's allow-list (which holds every principal's
//! key), are read only if no one but their owner may read or change them
//! ([`read_secret_file`]), and no error or `Debug` output of this module prints a key.
//!
//! The envelope's bytes (all integers little-endian):
//!
//! ```text
//! version        u8     = 1
//! principal_len  u8     1..=64
//! principal      [u8]   ASCII letters, digits, '-', '_', '.'
//! issued_unix_ms u64    the sender's realtime clock
//! nonce          [u8;16]
//! mac            [u8;32] HMAC-SHA256(key, "frond-control-v1" 0x00 key_expr 0x00
//!                                         issued_unix_ms nonce request_frame)
//! ```

use std::path::{Path, PathBuf};
use std::time::Duration;

use hmac::{Hmac, Mac};
use sha2::Sha256;

type HmacSha256 = Hmac<Sha256>;

/// Envelope format version.
pub const ENVELOPE_VERSION: u8 = 1;
/// Longest principal name.
pub const MAX_PRINCIPAL_LEN: usize = 64;
/// Shortest key, bytes (256 bits).
pub const MIN_KEY_BYTES: usize = 32;
/// Longest key, bytes.
pub const MAX_KEY_BYTES: usize = 256;
/// How long before the bridge's clock a request may have been issued: the time it takes to
/// arrive plus how far the sender's clock may be behind. Older requests are refused, so the
/// bridge need remember a nonce only this long.
pub const MAX_REQUEST_AGE: Duration = Duration::from_secs(30);
/// How far after the bridge's clock a request may have been issued: only the sender's clock
/// being ahead (hosts set by NTP differ by milliseconds), since travel makes a request older,
/// never younger. A request from further ahead is refused: accepting it would keep it valid
/// (and replayable against a bridge that had not yet seen it) for longer than [`MAX_REQUEST_AGE`].
pub const MAX_CLOCK_SKEW: Duration = Duration::from_secs(5);
/// Length of the nonce.
pub const NONCE_LEN: usize = 16;
/// Length of the MAC.
pub const MAC_LEN: usize = 32;
/// Largest key file read.
const MAX_KEY_FILE: u64 = 4096;
/// Domain separation: what the MAC is over starts with this.
const DOMAIN: &[u8] = b"frond-control-v1\0";

/// Why an envelope, a key or a key file is not acceptable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AuthError {
    /// No envelope in the query's attachment.
    #[error("the request carries no signature (frond control envelope)")]
    Missing,
    /// The envelope's bytes do not parse.
    #[error("malformed control envelope: {0}")]
    Malformed(&'static str),
    /// A principal name that is empty, too long or holds other characters.
    #[error("principal name {0:?}: 1 to 64 ASCII letters, digits, '-', '_' or '.'")]
    BadPrincipal(String),
    /// A key that is not hex or has the wrong length.
    #[error("control key: {0}")]
    BadKey(String),
    /// A key file that cannot be used.
    #[error("control key file {}: {reason}", path.display())]
    KeyFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it (never its content).
        reason: String,
    },
    /// A secret file (a key file, the bridge's allow-list) that its group or other users may
    /// read or change: a key others can read is no secret, and a file others can change lets
    /// them put in their own key.
    #[error(
        "{path}: mode {mode:03o}: {who}; it holds {holds}: chmod 600 {path}",
        path = path.display()
    )]
    Exposed {
        /// The file.
        path: PathBuf,
        /// Its permission bits.
        mode: u32,
        /// Who may do what (`its group may read it`).
        who: String,
        /// What it holds (`a control key, a secret`).
        holds: &'static str,
    },
}

/// Why a request's issue time is refused ([`check_issue_time`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum IssueTimeError {
    /// Issued more than [`MAX_REQUEST_AGE`] before the bridge's clock.
    #[error("issued {age_ms} ms before this host's clock; at most {} ms is accepted", MAX_REQUEST_AGE.as_millis())]
    TooOld {
        /// How long before.
        age_ms: u64,
    },
    /// Issued more than [`MAX_CLOCK_SKEW`] after the bridge's clock.
    #[error(
        "issued {ahead_ms} ms after this host's clock; at most {} ms of clock skew is accepted",
        MAX_CLOCK_SKEW.as_millis()
    )]
    Ahead {
        /// How long after.
        ahead_ms: u64,
    },
}

/// Whether a request issued at `issued_unix_ms` on its sender's clock is acceptable at
/// `now_unix_ms` on the receiver's: at most [`MAX_REQUEST_AGE`] before, at most
/// [`MAX_CLOCK_SKEW`] after (both bounds included).
pub fn check_issue_time(issued_unix_ms: u64, now_unix_ms: u64) -> Result<(), IssueTimeError> {
    if issued_unix_ms > now_unix_ms {
        let ahead_ms = issued_unix_ms - now_unix_ms;
        if ahead_ms > MAX_CLOCK_SKEW.as_millis() as u64 {
            return Err(IssueTimeError::Ahead { ahead_ms });
        }
    } else {
        let age_ms = now_unix_ms - issued_unix_ms;
        if age_ms > MAX_REQUEST_AGE.as_millis() as u64 {
            return Err(IssueTimeError::TooOld { age_ms });
        }
    }
    Ok(())
}

/// Whether `name` is a valid principal name.
pub fn check_principal(name: &str) -> Result<(), AuthError> {
    let ok = !name.is_empty()
        && name.len() <= MAX_PRINCIPAL_LEN
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'));
    if ok { Ok(()) } else { Err(AuthError::BadPrincipal(name.to_owned())) }
}

/// A principal's shared key.
#[derive(Clone, PartialEq, Eq)]
pub struct ControlKey(Vec<u8>);

impl std::fmt::Debug for ControlKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ControlKey({} bytes)", self.0.len())
    }
}

impl ControlKey {
    /// A key from its hex text (surrounding white space ignored): 32 to 256 bytes.
    pub fn from_hex(text: &str) -> Result<ControlKey, AuthError> {
        let text = text.trim();
        // hex's own message quotes the offending character: a piece of the secret.
        let bytes = hex::decode(text).map_err(|e| {
            AuthError::BadKey(match e {
                hex::FromHexError::InvalidHexCharacter { index, .. } => {
                    format!("not hex: character {} is not a hex digit", index + 1)
                }
                hex::FromHexError::OddLength | hex::FromHexError::InvalidStringLength => {
                    "not hex: an odd number of digits".to_owned()
                }
            })
        })?;
        if !(MIN_KEY_BYTES..=MAX_KEY_BYTES).contains(&bytes.len()) {
            return Err(AuthError::BadKey(format!(
                "{} bytes; it must be {MIN_KEY_BYTES} to {MAX_KEY_BYTES} bytes ({} to {} hex digits), \
                 e.g. from `openssl rand -hex 32`",
                bytes.len(),
                2 * MIN_KEY_BYTES,
                2 * MAX_KEY_BYTES
            )));
        }
        Ok(ControlKey(bytes))
    }

    /// Reads a key file: one hex key, a regular file of at most 4 KiB that only its owner may
    /// read or change ([`read_secret_file`]).
    pub fn read_file(path: &Path) -> Result<ControlKey, AuthError> {
        let text = read_secret_file(path, MAX_KEY_FILE, "a control key, a secret")?;
        ControlKey::from_hex(&text)
            .map_err(|e| AuthError::KeyFile { path: path.into(), reason: e.to_string() })
    }

    fn mac(&self) -> HmacSha256 {
        HmacSha256::new_from_slice(&self.0).expect("HMAC takes keys of any length")
    }
}

/// Who besides the owner may do what to a file of permission bits `mode`, in words (`its group
/// may read it, and other users may change it`); `None` when nobody may. The same rule and
/// words as the console's token file.
fn exposure(mode: u32) -> Option<String> {
    let who = |group: u32, others: u32| match (mode & group != 0, mode & others != 0) {
        (true, true) => Some("its group and other users"),
        (true, false) => Some("its group"),
        (false, true) => Some("other users"),
        (false, false) => None,
    };
    let said: Vec<String> = [(who(0o040, 0o004), "read"), (who(0o020, 0o002), "change")]
        .into_iter()
        .filter_map(|(who, what)| who.map(|w| format!("{w} may {what} it")))
        .collect();
    (!said.is_empty()).then(|| said.join(", and "))
}

/// Reads a secret file (a key file, the bridge's allow-list of keys; `holds` says what it holds,
/// for the error): a regular file of at most `max_bytes` that no one but its owner may read or
/// change (as `ssh` takes a private key). A file its group or other users may read or write is
/// refused with its mode and the fix ([`AuthError::Exposed`]). The file is opened without
/// blocking (a FIFO put in its place cannot hang the reader) and the checks are made on the
/// opened file, the one that is read.
pub fn read_secret_file(path: &Path, max_bytes: u64, holds: &'static str) -> Result<String, AuthError> {
    use std::io::Read;
    use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
    let err = |reason: String| AuthError::KeyFile { path: path.into(), reason };
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| err(e.to_string()))?;
    let meta = file.metadata().map_err(|e| err(e.to_string()))?;
    if !meta.is_file() {
        return Err(err("not a regular file".into()));
    }
    if meta.len() > max_bytes {
        return Err(err(format!("{} bytes; the limit is {max_bytes}", meta.len())));
    }
    let mode = meta.permissions().mode() & 0o777;
    if let Some(who) = exposure(mode) {
        return Err(AuthError::Exposed { path: path.into(), mode, who, holds });
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(max_bytes + 1).read_to_end(&mut bytes).map_err(|e| err(e.to_string()))?;
    if bytes.len() as u64 > max_bytes {
        return Err(err(format!("grew past the limit of {max_bytes} bytes while read")));
    }
    String::from_utf8(bytes).map_err(|_| err("not UTF-8 text".into()))
}

/// The proof a remote control request carries (see the module docs for its bytes).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Envelope {
    /// Who signs.
    pub principal: String,
    /// When, on the sender's realtime clock, milliseconds since 1970.
    pub issued_unix_ms: u64,
    /// Random, never reused.
    pub nonce: [u8; NONCE_LEN],
    /// HMAC-SHA256 of the request under the principal's key.
    pub mac: [u8; MAC_LEN],
}

/// Fixed part of an envelope: version, name length, time, nonce, MAC.
const FIXED_LEN: usize = 2 + 8 + NONCE_LEN + MAC_LEN;
/// Longest envelope.
pub const MAX_ENVELOPE_LEN: usize = FIXED_LEN + MAX_PRINCIPAL_LEN;

fn mac_input(mac: &mut HmacSha256, key_expr: &str, issued_unix_ms: u64, nonce: &[u8], frame: &[u8]) {
    mac.update(DOMAIN);
    mac.update(key_expr.as_bytes());
    mac.update(&[0]);
    mac.update(&issued_unix_ms.to_le_bytes());
    mac.update(nonce);
    mac.update(frame);
}

impl Envelope {
    /// Signs `frame` (an encoded control request) addressed to `key_expr` as `principal`.
    pub fn sign(
        key: &ControlKey,
        principal: &str,
        key_expr: &str,
        issued_unix_ms: u64,
        nonce: [u8; NONCE_LEN],
        frame: &[u8],
    ) -> Result<Envelope, AuthError> {
        check_principal(principal)?;
        let mut mac = key.mac();
        mac_input(&mut mac, key_expr, issued_unix_ms, &nonce, frame);
        let mac = mac.finalize().into_bytes().into();
        Ok(Envelope { principal: principal.to_owned(), issued_unix_ms, nonce, mac })
    }

    /// Whether the MAC is right for `frame` addressed to `key_expr` under `key` (compared in
    /// constant time).
    pub fn verify(&self, key: &ControlKey, key_expr: &str, frame: &[u8]) -> bool {
        let mut mac = key.mac();
        mac_input(&mut mac, key_expr, self.issued_unix_ms, &self.nonce, frame);
        mac.verify_slice(&self.mac).is_ok()
    }

    /// The envelope's bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FIXED_LEN + self.principal.len());
        out.push(ENVELOPE_VERSION);
        out.push(self.principal.len() as u8);
        out.extend_from_slice(self.principal.as_bytes());
        out.extend_from_slice(&self.issued_unix_ms.to_le_bytes());
        out.extend_from_slice(&self.nonce);
        out.extend_from_slice(&self.mac);
        out
    }

    /// Parses an envelope's bytes.
    pub fn decode(bytes: &[u8]) -> Result<Envelope, AuthError> {
        let (&version, rest) = bytes.split_first().ok_or(AuthError::Malformed("empty"))?;
        if version != ENVELOPE_VERSION {
            return Err(AuthError::Malformed("unknown version"));
        }
        let (&len, rest) = rest.split_first().ok_or(AuthError::Malformed("truncated"))?;
        let len = usize::from(len);
        if rest.len() != len + 8 + NONCE_LEN + MAC_LEN {
            return Err(AuthError::Malformed("wrong length"));
        }
        let (name, rest) = rest.split_at(len);
        let principal = std::str::from_utf8(name).map_err(|_| AuthError::Malformed("principal not UTF-8"))?;
        check_principal(principal)?;
        let (time, rest) = rest.split_at(8);
        let (nonce, mac) = rest.split_at(NONCE_LEN);
        Ok(Envelope {
            principal: principal.to_owned(),
            issued_unix_ms: u64::from_le_bytes(time.try_into().expect("8 bytes")),
            nonce: nonce.try_into().expect("16 bytes"),
            mac: mac.try_into().expect("32 bytes"),
        })
    }
}

/// A fresh random nonce.
pub fn new_nonce() -> [u8; NONCE_LEN] {
    let mut nonce = [0u8; NONCE_LEN];
    getrandom::fill(&mut nonce).expect("the OS random source works");
    nonce
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key() -> ControlKey {
        ControlKey::from_hex(&"0b".repeat(32)).unwrap()
    }

    #[test]
    fn hmac_sha256_matches_rfc_4231_test_case_2() {
        // RFC 4231, 4.3: key "Jefe", data "what do ya want for nothing?".
        let mut mac = HmacSha256::new_from_slice(b"Jefe").unwrap();
        mac.update(b"what do ya want for nothing?");
        assert_eq!(
            hex::encode(mac.finalize().into_bytes()),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"
        );
    }

    #[test]
    fn envelope_bytes_are_as_documented() {
        let env = Envelope {
            principal: "ab".into(),
            issued_unix_ms: 0x0102,
            nonce: [7; NONCE_LEN],
            mac: [9; MAC_LEN],
        };
        let bytes = env.encode();
        let mut expected = vec![1, 2, b'a', b'b', 0x02, 0x01, 0, 0, 0, 0, 0, 0];
        expected.extend([7; NONCE_LEN]);
        expected.extend([9; MAC_LEN]);
        assert_eq!(bytes, expected);
        assert_eq!(Envelope::decode(&bytes).unwrap(), env);
    }

    #[test]
    fn the_mac_covers_the_documented_bytes() {
        // The same MAC computed from the module docs' layout, by hand.
        let env = Envelope::sign(&key(), "director", "frond/s/g/control", 42, [3; 16], b"FRAME").unwrap();
        let mut mac = HmacSha256::new_from_slice(&[0x0b; 32]).unwrap();
        let mut input = b"frond-control-v1\0frond/s/g/control\0".to_vec();
        input.extend(42u64.to_le_bytes());
        input.extend([3; 16]);
        input.extend(b"FRAME");
        mac.update(&input);
        assert_eq!(env.mac.as_slice(), mac.finalize().into_bytes().as_slice());
    }

    #[test]
    fn verification_fails_for_any_change() {
        let env = Envelope::sign(&key(), "director", "frond/s/g/control", 42, [3; 16], b"FRAME").unwrap();
        assert!(env.verify(&key(), "frond/s/g/control", b"FRAME"));
        assert!(!env.verify(&key(), "frond/s/h/control", b"FRAME"), "another source");
        assert!(!env.verify(&key(), "frond/s/g/control", b"FRAMF"), "another request");
        let other = ControlKey::from_hex(&"0c".repeat(32)).unwrap();
        assert!(!env.verify(&other, "frond/s/g/control", b"FRAME"), "another key");
        let later = Envelope { issued_unix_ms: 43, ..env.clone() };
        assert!(!later.verify(&key(), "frond/s/g/control", b"FRAME"), "another time");
        let renonced = Envelope { nonce: [4; 16], ..env };
        assert!(!renonced.verify(&key(), "frond/s/g/control", b"FRAME"), "another nonce");
    }

    #[test]
    fn bad_envelopes_and_keys_are_named() {
        assert_eq!(Envelope::decode(&[]), Err(AuthError::Malformed("empty")));
        assert_eq!(Envelope::decode(&[2]), Err(AuthError::Malformed("unknown version")));
        assert_eq!(Envelope::decode(&[1, 3, b'a']), Err(AuthError::Malformed("wrong length")));
        let mut bad_name =
            Envelope { principal: "ab".into(), issued_unix_ms: 0, nonce: [0; 16], mac: [0; 32] }.encode();
        bad_name[2] = b'/';
        assert!(matches!(Envelope::decode(&bad_name), Err(AuthError::BadPrincipal(_))));
        assert!(ControlKey::from_hex("zz").is_err());
        assert!(ControlKey::from_hex(&"00".repeat(31)).is_err(), "too short");
        assert!(ControlKey::from_hex(&format!(" {}\n", "00".repeat(32))).is_ok());
        assert!(check_principal(&"a".repeat(65)).is_err());
        assert!(check_principal("").is_err());
    }

    #[test]
    fn key_files_that_their_group_or_others_may_read_or_change_are_refused_with_the_fix() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("key");
        let secret = "5ec7e7".repeat(11)[..64].to_owned();
        std::fs::write(&path, &secret).unwrap();
        let shown = path.display().to_string();
        // Each mode, and who the message must name (the console's token file's words).
        for (mode, who) in [
            (0o640, "its group may read it"),
            (0o604, "other users may read it"),
            (0o644, "its group and other users may read it"),
            (0o620, "its group may change it"),
            (0o602, "other users may change it"),
            (0o660, "its group may read it, and its group may change it"),
            (0o666, "its group and other users may read it, and its group and other users may change it"),
        ] {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
            let e = ControlKey::read_file(&path).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!(
                    "{shown}: mode {mode:03o}: {who}; it holds a control key, a secret: chmod 600 {shown}"
                )
            );
            assert!(!format!("{e} {e:?}").contains(&secret[..8]), "the key leaked: {e:?}");
        }
        for mode in [0o600, 0o400, 0o700] {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
            assert_eq!(
                ControlKey::read_file(&path).unwrap(),
                ControlKey::from_hex(&secret).unwrap(),
                "{mode:o}"
            );
        }
        assert!(ControlKey::read_file(dir.path()).unwrap_err().to_string().contains("not a regular file"));
    }

    #[test]
    fn a_key_file_that_is_not_a_key_is_named_without_printing_what_it_holds() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("key");
        // A base64 secret pasted where a hex key belongs, and a hex key one digit short.
        for (text, said) in [
            ("c2VjcmV0LXNlY3JldC1zZWNyZXQtc2VjcmV0LXNlY3JldA==", "character 3 is not a hex digit"),
            (&"ab".repeat(32)[1..], "an odd number of digits"),
        ] {
            std::fs::write(&path, text).unwrap();
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
            let e = ControlKey::read_file(&path).unwrap_err();
            let shown = format!("{e} {e:?}");
            assert!(shown.contains(said), "{shown}");
            // No piece of the file: not its first characters, not the one that is not hex.
            assert!(!shown.contains(&text[..4]) && !shown.contains("'V'"), "{shown}");
        }
        assert_eq!(format!("{:?}", ControlKey::from_hex(&"ab".repeat(32)).unwrap()), "ControlKey(32 bytes)");
    }

    #[test]
    fn issue_times_are_accepted_from_30_s_before_to_5_s_after_the_clock() {
        let now = 1_000_000;
        assert_eq!(check_issue_time(now, now), Ok(()));
        assert_eq!(check_issue_time(now - 30_000, now), Ok(()));
        assert_eq!(check_issue_time(now - 30_001, now), Err(IssueTimeError::TooOld { age_ms: 30_001 }));
        assert_eq!(check_issue_time(now + 5_000, now), Ok(()));
        assert_eq!(check_issue_time(now + 5_001, now), Err(IssueTimeError::Ahead { ahead_ms: 5_001 }));
        assert_eq!(check_issue_time(u64::MAX, 0), Err(IssueTimeError::Ahead { ahead_ms: u64::MAX }));
        assert_eq!(check_issue_time(0, u64::MAX), Err(IssueTimeError::TooOld { age_ms: u64::MAX }));
    }
}
