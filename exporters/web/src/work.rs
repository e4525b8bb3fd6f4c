//! A bound on heavy work at once (baking a take, scanning takes, encoding a large answer): a
//! few requests do it, as many again wait a little, and the rest are answered 503 at once, so
//! that however many arrive together, memory and CPU stay within what a few cost, and the
//! connections waiting are few: a waiting connection cannot be evicted (it has its request), so
//! 80 clients asking for a take again and again, each waiting 5 s for its turn, held every
//! place of the server's gate and the operator's requests were 503.

use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

/// Permits for heavy work.
#[derive(Debug)]
pub struct WorkLimit {
    max: usize,
    busy: Mutex<Busyness>,
    freed: Condvar,
}

/// Work running and waiting.
#[derive(Debug, Default)]
struct Busyness {
    running: usize,
    waiting: usize,
}

/// Heavy work was refused: every permit stayed taken for the whole wait, or as many requests
/// as there are permits were waiting already.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("busy: {max} heavy requests are being answered; try again")]
pub struct Busy {
    /// The permits.
    pub max: usize,
}

impl WorkLimit {
    /// `max` permits (at least 1); at most `max` more wait for one.
    pub fn new(max: usize) -> WorkLimit {
        WorkLimit { max: max.max(1), busy: Mutex::default(), freed: Condvar::new() }
    }

    /// Runs `work` once a permit is free, waiting at most `wait` for one; refused at once when
    /// as many as the permits wait already.
    pub fn run<T>(&self, wait: Duration, work: impl FnOnce() -> T) -> Result<T, Busy> {
        let until = Instant::now() + wait;
        let mut busy = self.busy.lock().unwrap_or_else(|e| e.into_inner());
        if busy.running >= self.max {
            if busy.waiting >= self.max {
                return Err(Busy { max: self.max });
            }
            busy.waiting += 1;
            while busy.running >= self.max {
                let left = until.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    busy.waiting -= 1;
                    return Err(Busy { max: self.max });
                }
                busy = self.freed.wait_timeout(busy, left).unwrap_or_else(|e| e.into_inner()).0;
            }
            busy.waiting -= 1;
        }
        busy.running += 1;
        drop(busy);
        struct Permit<'a>(&'a WorkLimit);
        impl Drop for Permit<'_> {
            fn drop(&mut self) {
                self.0.busy.lock().unwrap_or_else(|e| e.into_inner()).running -= 1;
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

    /// A thread that holds `limit`'s one permit until told: the sender that tells it, and the
    /// thread. Returns once the permit is taken.
    fn hold_the_permit(
        limit: &Arc<WorkLimit>,
    ) -> (mpsc::Sender<()>, std::thread::JoinHandle<Result<(), Busy>>) {
        let (started, wait_started) = mpsc::channel();
        let (release, released) = mpsc::channel::<()>();
        let l = Arc::clone(limit);
        let holder = std::thread::spawn(move || {
            l.run(Duration::ZERO, || {
                started.send(()).unwrap();
                released.recv().unwrap();
            })
        });
        wait_started.recv().unwrap();
        (release, holder)
    }

    #[test]
    fn work_past_the_permits_waits_then_is_refused() {
        let limit = Arc::new(WorkLimit::new(1));
        let (release, holder) = hold_the_permit(&limit);
        assert_eq!(limit.run(Duration::from_millis(20), || 1), Err(Busy { max: 1 }));
        release.send(()).unwrap();
        holder.join().unwrap().unwrap();
        assert_eq!(limit.run(Duration::ZERO, || 2), Ok(2));
    }

    /// Past the permits, only as many requests as there are permits wait; the next is refused
    /// at once instead of holding its connection for the whole wait.
    #[test]
    fn only_as_many_as_the_permits_wait() {
        let limit = Arc::new(WorkLimit::new(1));
        let (release, holder) = hold_the_permit(&limit);
        let l = Arc::clone(&limit);
        let waiter = std::thread::spawn(move || l.run(Duration::from_secs(60), || 3));
        while limit.busy.lock().unwrap().waiting == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
        let asked = Instant::now();
        assert_eq!(limit.run(Duration::from_secs(60), || 4), Err(Busy { max: 1 }));
        assert!(asked.elapsed() < Duration::from_secs(30), "the third waited");
        release.send(()).unwrap();
        holder.join().unwrap().unwrap();
        assert_eq!(waiter.join().unwrap(), Ok(3));
        assert_eq!(limit.run(Duration::ZERO, || 5), Ok(5));
        let b = limit.busy.lock().unwrap();
        assert_eq!((b.running, b.waiting), (0, 0));
    }
}
