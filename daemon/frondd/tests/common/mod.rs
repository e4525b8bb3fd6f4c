//! Helpers shared by the loop's integration tests: subscriber sockets and direct-lane admission.

use std::os::fd::AsRawFd;
use std::os::unix::net::UnixStream;
use std::sync::Arc;

use frondd::engine::LoopCommand;
use frondd::handoff::SubscriberCounters;

/// A subscriber socket pair: the daemon's end and the subscriber's end. `small`: a small send
/// buffer on the daemon's end, so a subscriber that does not read fills it within a few dozen
/// frames.
pub fn subscriber_pair(small: bool) -> (UnixStream, UnixStream) {
    let (daemon_end, sub_end) = UnixStream::pair().unwrap();
    if !small {
        return (daemon_end, sub_end);
    }
    let size: libc::c_int = 4096;
    // SAFETY: a valid socket and a c_int option value of its size.
    let rc = unsafe {
        libc::setsockopt(
            daemon_end.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_SNDBUF,
            (&size as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    assert_eq!(rc, 0);
    (daemon_end, sub_end)
}

/// The command that puts the subscriber on `stream` on a direct lane, with a grass `Hello`.
pub fn new_lane(id: u64, stream: UnixStream, counters: Arc<SubscriberCounters>) -> LoopCommand {
    let hello = frond_protocol::Hello {
        protocol_version: frond_protocol::PROTOCOL_VERSION,
        daemon_version: "test".into(),
        rig_name: "grass".into(),
        joint_names: vec!["root".into(), "stem".into(), "upper".into(), "tip".into()],
        tick_rate_hz: 1000,
        elements: Default::default(),
        next_seq: 0,
    };
    LoopCommand::AddSubscriber(Box::new(frondd::handoff::NewLane::new(
        id,
        stream,
        counters,
        frond_protocol::PatchableHello::new(&hello),
    )))
}
