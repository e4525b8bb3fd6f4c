//! Who may use the control socket: the peer's credentials (`SO_PEERCRED`, `SO_PEERGROUPS`)
//! against the daemon's user and group and the config's `control.allowed_uids` /
//! `control.allowed_gids`.

use std::os::unix::net::UnixStream;

/// Who may use the control socket, checked against the peer's credentials (SO_PEERCRED and
/// SO_PEERGROUPS): root, the daemon's user, members of the daemon's group (the group the socket
/// directory and the sockets belong to, whose file modes already let them connect), and the
/// users and groups the config adds.
#[derive(Debug, Clone, Default)]
pub struct AccessPolicy {
    /// The daemon's effective uid (always allowed, as is root).
    pub own_uid: u32,
    /// The daemon's effective gid (its members are allowed: the `frond` group of the service).
    pub own_gid: u32,
    /// Extra allowed users.
    pub allowed_uids: Vec<u32>,
    /// Allowed groups (the client's primary or supplementary groups).
    pub allowed_gids: Vec<u32>,
}

/// A connected client's credentials.
#[derive(Debug, Clone)]
pub struct PeerCred {
    /// Process id.
    pub pid: i32,
    /// User id.
    pub uid: u32,
    /// Primary group id.
    pub gid: u32,
    /// Supplementary groups, as the socket reports them (`SO_PEERGROUPS`: no `/proc` read,
    /// which `ProtectProc=invisible` would hide).
    pub groups: Vec<u32>,
}

/// Most supplementary groups read for a client (Linux allows 65536; the buffer grows to what
/// the kernel says it needs, up to this).
const MAX_PEER_GROUPS: usize = 65_536;

/// `SO_PEERGROUPS` (Linux 4.13): the supplementary groups of the peer of a Unix socket.
const SO_PEERGROUPS: libc::c_int = 59;

/// Reads SO_PEERGROUPS of a connected Unix socket.
fn peer_groups(stream: &UnixStream) -> std::io::Result<Vec<u32>> {
    use std::os::fd::AsRawFd;
    let mut groups: Vec<libc::gid_t> = vec![0; 64];
    loop {
        let mut len = (groups.len() * std::mem::size_of::<libc::gid_t>()) as libc::socklen_t;
        // SAFETY: `groups` is valid for writes of `len` bytes; the fd is a live socket.
        let rc = unsafe {
            libc::getsockopt(
                stream.as_raw_fd(),
                libc::SOL_SOCKET,
                SO_PEERGROUPS,
                groups.as_mut_ptr().cast(),
                &mut len,
            )
        };
        let n = len as usize / std::mem::size_of::<libc::gid_t>();
        if rc == 0 {
            groups.truncate(n);
            return Ok(groups);
        }
        let e = std::io::Error::last_os_error();
        // ERANGE: `len` now says how much room it needs.
        if e.raw_os_error() == Some(libc::ERANGE) && n > groups.len() && n <= MAX_PEER_GROUPS {
            groups.resize(n, 0);
            continue;
        }
        return Err(e);
    }
}

/// Reads SO_PEERCRED of a connected Unix socket.
pub fn peer_cred(stream: &UnixStream) -> std::io::Result<PeerCred> {
    use std::os::fd::AsRawFd;
    let mut cred = libc::ucred { pid: 0, uid: 0, gid: 0 };
    let mut len = std::mem::size_of::<libc::ucred>() as libc::socklen_t;
    // SAFETY: `cred` and `len` are valid for writes of the sizes passed; the fd is a live socket.
    let rc = unsafe {
        libc::getsockopt(
            stream.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_PEERCRED,
            (&mut cred as *mut libc::ucred).cast(),
            &mut len,
        )
    };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(PeerCred { pid: cred.pid, uid: cred.uid, gid: cred.gid, groups: peer_groups(stream)? })
}

/// Why a client may not use the control socket.
#[derive(Debug, thiserror::Error)]
pub enum AccessError {
    /// `SO_PEERCRED` failed.
    #[error("cannot read the client's credentials: {0}")]
    Credentials(#[source] std::io::Error),
    /// Neither the client's user nor any of its groups is allowed.
    #[error(
        "uid {uid} (gid {gid}) is not allowed on the control socket; add the user to the daemon's group, \
         or add it to control.allowed_uids or one of its groups to control.allowed_gids in the daemon's \
         config"
    )]
    NotAllowed {
        /// The client's uid.
        uid: u32,
        /// The client's primary gid.
        gid: u32,
    },
}

impl AccessPolicy {
    /// Whether `peer` may use the control socket; `Err` says why not.
    pub fn check(&self, peer: &PeerCred) -> Result<(), AccessError> {
        if peer.uid == 0 || peer.uid == self.own_uid || self.allowed_uids.contains(&peer.uid) {
            return Ok(());
        }
        let allowed = |g: &u32| *g == self.own_gid || self.allowed_gids.contains(g);
        if allowed(&peer.gid) || peer.groups.iter().any(allowed) {
            return Ok(());
        }
        Err(AccessError::NotAllowed { uid: peer.uid, gid: peer.gid })
    }
}

#[cfg(test)]
mod access_tests {
    use super::*;

    fn peer(uid: u32, gid: u32, groups: &[u32]) -> PeerCred {
        PeerCred { pid: 1, uid, gid, groups: groups.to_vec() }
    }

    /// Issue 18: members of the daemon's group (the service's `frond` group) are allowed by
    /// default, whether it is their primary or a supplementary group; others are not, unless the
    /// config names them.
    #[test]
    fn the_daemons_group_is_allowed_and_others_are_not() {
        let p = AccessPolicy { own_uid: 900, own_gid: 901, allowed_uids: vec![], allowed_gids: vec![] };
        assert!(p.check(&peer(0, 0, &[])).is_ok(), "root");
        assert!(p.check(&peer(900, 5, &[])).is_ok(), "the daemon's user");
        assert!(p.check(&peer(1000, 901, &[])).is_ok(), "primary group");
        assert!(p.check(&peer(1000, 1000, &[27, 901])).is_ok(), "supplementary group");
        let e = p.check(&peer(1000, 1000, &[27])).unwrap_err().to_string();
        assert!(e.contains("uid 1000 (gid 1000) is not allowed"), "{e}");
        let q = AccessPolicy { allowed_gids: vec![27], ..p };
        assert!(q.check(&peer(1000, 1000, &[27])).is_ok(), "a group the config adds");
    }

    /// SO_PEERGROUPS of a socket pair in this process gives this process's own groups.
    #[test]
    fn peer_groups_are_read_from_the_socket() {
        let (a, _b) = UnixStream::pair().unwrap();
        let mut want = vec![0 as libc::gid_t; 256];
        // SAFETY: `want` has room for 256 gids, the size passed.
        let n = unsafe { libc::getgroups(want.len() as libc::c_int, want.as_mut_ptr()) };
        assert!(n >= 0);
        want.truncate(n as usize);
        let mut got = peer_groups(&a).unwrap();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want);
    }
}
