//! Waiting a bounded time for a helper thread at shutdown: a thread whose read or connect
//! blocks anyway (a stalled pipe, a name lookup) must not keep the daemon from stopping, so it is
//! left to end with the process. One rule for the hand sources' threads and frondd's own.

use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Joins `handle` if the thread ends within `wait` (checked every 5 ms): `Some` with its
/// result, or `None` when it is still running, in which case it is detached (it ends with the
/// process) and the caller says so.
pub fn join_within<T>(handle: JoinHandle<T>, wait: Duration) -> Option<std::thread::Result<T>> {
    let deadline = Instant::now() + wait;
    while !handle.is_finished() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    handle.is_finished().then(|| handle.join())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_that_ends_is_joined_and_one_that_blocks_is_left() {
        let quick = std::thread::spawn(|| 7);
        assert!(matches!(join_within(quick, Duration::from_secs(5)), Some(Ok(7))));
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let stuck = std::thread::spawn(move || rx.recv().ok());
        let started = Instant::now();
        assert!(join_within(stuck, Duration::from_millis(50)).is_none());
        assert!(started.elapsed() >= Duration::from_millis(50));
        drop(tx);
    }
}
