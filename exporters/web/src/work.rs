//! A bound on heavy work at once (baking a take, scanning takes, encoding a large answer): a
//! few requests do it, the rest wait a little and are then answered 503, so that however many
//! arrive together, memory and CPU stay within what a few cost.

use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

/// Permits for heavy work.
#[derive(Debug)]
pub struct WorkLimit {
    max: usize,
    busy: Mutex<usize>,
    freed: Condvar,
}

/// Heavy work was refused: every permit stayed taken for the whole wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("busy: {max} heavy requests are being answered; try again")]
pub struct Busy {
    /// The permits.
    pub max: usize,
}

impl WorkLimit {
    /// `max` permits (at least 1).
    pub fn new(max: usize) -> WorkLimit {
        WorkLimit { max: max.max(1), busy: Mutex::new(0), freed: Condvar::new() }
    }

    /// Runs `work` once a permit is free, waiting at most `wait` for one.
    pub fn run<T>(&self, wait: Duration, work: impl FnOnce() -> T) -> Result<T, Busy> {
        let until = Instant::now() + wait;
        let mut busy = self.busy.lock().unwrap_or_else(|e| e.into_inner());
        while *busy >= self.max {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(Busy { max: self.max });
            }
            busy = self.freed.wait_timeout(busy, left).unwrap_or_else(|e| e.into_inner()).0;
        }
        *busy += 1;
        drop(busy);
        struct Permit<'a>(&'a WorkLimit);
        impl Drop for Permit<'_> {
            fn drop(&mut self) {
                *self.0.busy.lock().unwrap_or_else(|e| e.into_inner()) -= 1;
                self.0.freed.notify_one();
            }
        }
        let _permit = Permit(self);
        Ok(work())
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::mpsc;

    use super::*;

    #[test]
    fn work_past_the_permits_waits_then_is_refused() {
        let limit = Arc::new(WorkLimit::new(1));
        let (started, wait_started) = mpsc::channel();
        let (release, released) = mpsc::channel::<()>();
        let l = Arc::clone(&limit);
        let holder = std::thread::spawn(move || {
            l.run(Duration::ZERO, || {
                started.send(()).unwrap();
                released.recv().unwrap();
            })
        });
        wait_started.recv().unwrap();
        assert_eq!(limit.run(Duration::from_millis(20), || 1), Err(Busy { max: 1 }));
        release.send(()).unwrap();
        holder.join().unwrap().unwrap();
        assert_eq!(limit.run(Duration::ZERO, || 2), Ok(2));
    }
}
