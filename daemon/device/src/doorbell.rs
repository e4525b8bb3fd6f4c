//! [`Doorbell`]: an `eventfd` a producer thread rings and the realtime loop polls, the ready
//! descriptor ([`crate::HandSource::ready_fd`]) of sources whose reports arrive through an
//! in-process queue (the in-process virtual glove, OSC input).

use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};

/// A non-blocking `eventfd`: rung when there is something to read, drained by the reader before
/// it empties its queue (so a report queued after the drain rings it again).
#[derive(Debug)]
pub struct Doorbell(OwnedFd);

impl Doorbell {
    /// A new, quiet doorbell.
    pub fn new() -> std::io::Result<Self> {
        // SAFETY: eventfd has no memory-safety preconditions; a valid result is a new descriptor
        // we own from here on.
        let fd = unsafe { libc::eventfd(0, libc::EFD_NONBLOCK | libc::EFD_CLOEXEC) };
        if fd < 0 {
            return Err(std::io::Error::last_os_error());
        }
        // SAFETY: `fd` was just returned by eventfd and is owned by nobody else.
        Ok(Doorbell(unsafe { OwnedFd::from_raw_fd(fd) }))
    }

    /// Makes the descriptor readable (never blocks; a saturated counter is readable anyway).
    pub fn ring(&self) {
        let one = 1u64.to_ne_bytes();
        // SAFETY: writes 8 bytes from a valid buffer to our own non-blocking eventfd.
        unsafe { libc::write(self.0.as_raw_fd(), one.as_ptr().cast(), one.len()) };
    }

    /// Makes it quiet again (never blocks, allocates nothing).
    pub fn drain(&self) {
        let mut v = [0u8; 8];
        // SAFETY: reads at most 8 bytes into a valid buffer from our own non-blocking eventfd.
        unsafe { libc::read(self.0.as_raw_fd(), v.as_mut_ptr().cast(), v.len()) };
    }

    /// The descriptor to poll for `POLLIN`.
    pub fn fd(&self) -> RawFd {
        self.0.as_raw_fd()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn readable(b: &Doorbell) -> bool {
        let mut pfd = libc::pollfd { fd: b.fd(), events: libc::POLLIN, revents: 0 };
        // SAFETY: one valid pollfd, zero timeout.
        unsafe { libc::poll(&mut pfd, 1, 0) == 1 }
    }

    #[test]
    fn rings_until_drained() {
        let b = Doorbell::new().unwrap();
        assert!(!readable(&b));
        b.ring();
        b.ring();
        assert!(readable(&b));
        b.drain();
        assert!(!readable(&b), "one drain quiets any number of rings");
        b.drain();
        assert!(!readable(&b), "draining a quiet bell neither blocks nor rings it");
    }
}
