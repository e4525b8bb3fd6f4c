//! Monotonic clock and absolute-deadline sleep (`clock_nanosleep(TIMER_ABSTIME)`).

/// Nanoseconds per second.
pub const NS_PER_S: u64 = 1_000_000_000;

/// Host `CLOCK_MONOTONIC` in nanoseconds.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * NS_PER_S + ts.tv_nsec as u64
}

/// Sleeps until the absolute `CLOCK_MONOTONIC` time `deadline_ns`, retrying on signals.
///
/// An absolute deadline does not drift: a late wake-up does not push every later tick back.
pub fn sleep_until_ns(deadline_ns: u64) {
    let ts = timespec_ns(deadline_ns);
    loop {
        // SAFETY: `ts` is a valid timespec; the remainder pointer may be null with TIMER_ABSTIME.
        let rc = unsafe {
            libc::clock_nanosleep(libc::CLOCK_MONOTONIC, libc::TIMER_ABSTIME, &ts, std::ptr::null_mut())
        };
        if rc != libc::EINTR {
            return;
        }
    }
}

/// What ended a [`wait_any_readable_until_ns`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Woke {
    /// The deadline passed.
    Deadline,
    /// The descriptor is readable (or hung up or in error: the next read says which).
    Readable,
}

fn timespec_ns(ns: u64) -> libc::timespec {
    libc::timespec { tv_sec: (ns / NS_PER_S) as libc::time_t, tv_nsec: (ns % NS_PER_S) as libc::c_long }
}

/// Waits until one of `fds` is readable or the absolute `CLOCK_MONOTONIC` time `deadline_ns`,
/// whichever comes first, retrying on signals. The realtime loop's wait when its hand sources
/// have descriptors: a report on any of them wakes it at once instead of waiting for the next
/// tick, and the deadline stays absolute (the remaining time is recomputed on every retry, so a
/// signal cannot stretch it). `ppoll` takes a relative timeout, so this costs one
/// `clock_gettime` (vDSO) per wait. Each entry's `events` should be `POLLIN`; `revents` is
/// overwritten. Never allocates.
pub fn wait_any_readable_until_ns(fds: &mut [libc::pollfd], deadline_ns: u64) -> Woke {
    loop {
        let now = monotonic_ns();
        if now >= deadline_ns {
            return Woke::Deadline;
        }
        let timeout = timespec_ns(deadline_ns - now);
        // SAFETY: `fds` is a valid, exclusively borrowed array of `fds.len()` pollfds; `timeout`
        // is a valid timespec; no signal mask is changed.
        let rc =
            unsafe { libc::ppoll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, &timeout, std::ptr::null()) };
        match rc {
            0 => return Woke::Deadline,
            n if n > 0 => return Woke::Readable,
            _ if std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted => continue,
            // EBADF/ENOMEM/EINVAL: report readable so the caller's read finds and reports it.
            _ => return Woke::Readable,
        }
    }
}

/// Waits up to `timeout` for `fd` (a listening socket, say) to be readable; `false` on timeout.
/// Helper threads use it instead of sleeping in a polling loop, so an idle daemon does not wake
/// fifty times a second per listener.
pub fn wait_readable(fd: std::os::fd::BorrowedFd<'_>, timeout: std::time::Duration) -> bool {
    use std::os::fd::AsRawFd;
    let mut pfd = libc::pollfd { fd: fd.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    let ms = timeout.as_millis().min(i32::MAX as u128) as i32;
    // SAFETY: one valid pollfd borrowed for the duration of the call.
    unsafe { libc::poll(&mut pfd, 1, ms) > 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wait_readable_until_ns(fd: std::os::fd::RawFd, deadline_ns: u64) -> Woke {
        wait_any_readable_until_ns(&mut [libc::pollfd { fd, events: libc::POLLIN, revents: 0 }], deadline_ns)
    }

    #[test]
    fn sleep_until_never_returns_early() {
        let start = monotonic_ns();
        let deadline = start + 2_000_000;
        sleep_until_ns(deadline);
        assert!(monotonic_ns() >= deadline);
    }

    #[test]
    fn wait_readable_wakes_on_data_before_the_deadline_and_at_it_without() {
        use std::io::Write;
        use std::os::fd::AsRawFd;
        let (mut a, b) = std::os::unix::net::UnixStream::pair().unwrap();
        // Nothing to read: returns at the deadline, not before.
        let deadline = monotonic_ns() + 3_000_000;
        assert_eq!(wait_readable_until_ns(b.as_raw_fd(), deadline), Woke::Deadline);
        assert!(monotonic_ns() >= deadline);
        // Data pending: returns readable long before a far deadline.
        a.write_all(b"x").unwrap();
        let far = monotonic_ns() + 60 * NS_PER_S;
        assert_eq!(wait_readable_until_ns(b.as_raw_fd(), far), Woke::Readable);
        assert!(monotonic_ns() < far);
        // A deadline already past returns at once without polling.
        assert_eq!(wait_readable_until_ns(b.as_raw_fd(), 0), Woke::Deadline);
        // The helper-thread wait: readable now, then times out on a drained peer.
        assert!(wait_readable(std::os::fd::AsFd::as_fd(&b), std::time::Duration::from_millis(1)));
        let (_c, d) = std::os::unix::net::UnixStream::pair().unwrap();
        assert!(!wait_readable(std::os::fd::AsFd::as_fd(&d), std::time::Duration::from_millis(1)));
    }

    #[test]
    fn past_deadline_returns_immediately() {
        let before = monotonic_ns();
        sleep_until_ns(before.saturating_sub(NS_PER_S));
        // Returns at all (no hang) and the clock only moves forward.
        assert!(monotonic_ns() >= before);
    }
}
