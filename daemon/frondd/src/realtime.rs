//! The realtime thread: paces [`Engine::tick`] on absolute deadlines.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::thread;

use crate::clock::{NS_PER_S, Woke, monotonic_ns, sleep_until_ns, wait_any_readable_until_ns};
use crate::engine::Engine;
use crate::stats::LoopStats;

/// What realtime tuning was obtained, for the log and `frond status`.
#[derive(Debug, Clone, Default)]
pub struct RealtimeReport {
    /// SCHED_FIFO priority in force, or the reason it is not.
    pub scheduling: String,
    /// mlockall outcome.
    pub memory_lock: String,
}

/// Asks for SCHED_FIFO at `priority` (if non-zero) for the calling thread.
fn set_fifo(priority: u8) -> String {
    if priority == 0 {
        return "normal (realtime.priority = 0)".into();
    }
    let param = libc::sched_param { sched_priority: i32::from(priority) };
    // SAFETY: `param` is a valid sched_param; pid 0 means the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        format!("SCHED_FIFO priority {priority}")
    } else {
        format!("normal (SCHED_FIFO {priority} refused: {})", std::io::Error::last_os_error())
    }
}

/// Locks all current and future pages in memory when asked.
pub fn lock_memory(enabled: bool) -> String {
    if !enabled {
        return "off (realtime.lock_memory = false)".into();
    }
    // SAFETY: mlockall has no memory-safety preconditions.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 { "locked".into() } else { format!("refused: {}", std::io::Error::last_os_error()) }
}

/// Pins the thread `handle` runs on to `cpu`; reports the outcome.
pub fn pin_thread<T>(handle: &thread::JoinHandle<T>, cpu: Option<usize>) -> String {
    use std::os::unix::thread::JoinHandleExt;
    let Some(cpu) = cpu else { return "none (realtime.cpu = -1)".into() };
    if cpu >= libc::CPU_SETSIZE as usize {
        return format!("refused: CPU {cpu} is beyond CPU_SETSIZE");
    }
    // SAFETY: cpu_set_t is plain data; CPU_ZERO/CPU_SET only write inside it (cpu < CPU_SETSIZE).
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    // SAFETY: as above.
    unsafe {
        libc::CPU_ZERO(&mut set);
        libc::CPU_SET(cpu, &mut set);
    }
    // SAFETY: the pthread handle is alive (we hold its JoinHandle); `set` is a valid cpu_set_t.
    let rc = unsafe {
        libc::pthread_setaffinity_np(handle.as_pthread_t(), std::mem::size_of::<libc::cpu_set_t>(), &set)
    };
    if rc == 0 {
        format!("CPU {cpu}")
    } else {
        format!("refused for CPU {cpu}: {}", std::io::Error::from_raw_os_error(rc))
    }
}

/// Asks for 1 ns timer slack on the calling thread (the default 50 us lets the kernel
/// coalesce a normal-priority thread's wake-ups that much later; SCHED_FIFO threads have none).
fn set_timer_slack_1ns() {
    set_timer_slack_ns(1);
}

fn set_timer_slack_ns(ns: u64) {
    // SAFETY: PR_SET_TIMERSLACK takes an integer argument and affects only the calling thread.
    unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, ns as libc::c_ulong, 0, 0, 0) };
}

/// Timer slack of the loop's waits while a hand source's reports cover every tick.
pub const STREAMING_SLACK_NS: u64 = 2_000_000;
/// Ticks in a row that reports must cover before the loop waits with [`STREAMING_SLACK_NS`].
pub const STREAMING_AFTER_TICKS: u32 = 64;
/// Most ticks a late tick after a relaxed wait catches up on at once.
const MAX_CATCH_UP_TICKS: u32 = 64;

/// The waits' timer precision. While a source's reports cover every tick, the deadline only
/// matters if the source falls silent, and a precise timer armed and cancelled for every wait
/// costs more than reading the report (a hardware timer reprogramming each way; on a virtual
/// machine, a trap to the hypervisor each). After [`STREAMING_AFTER_TICKS`] covered ticks in a
/// row the loop waits with [`STREAMING_SLACK_NS`] of slack, which lets the kernel serve the
/// deadline with a timer interrupt already due instead of programming one. The first tick after
/// the source falls silent may come that much late: it catches up on the periods it slept
/// through (a held frame each, no overrun counted, no lateness recorded, since no report was
/// waiting), and every tick that runs makes the waits precise again. SCHED_FIFO threads get no
/// slack from the kernel, so with `realtime.priority` set the waits stay precise throughout.
#[derive(Debug, Default)]
struct WaitPrecision {
    covered_in_row: u32,
    relaxed: bool,
}

impl WaitPrecision {
    /// Reports covered the upcoming tick; `every_tick` when the engine must run every tick
    /// anyway (stages, several hands), which keeps the waits precise.
    fn covered(&mut self, every_tick: bool) {
        self.covered_in_row = self.covered_in_row.saturating_add(1);
        if !self.relaxed && !every_tick && self.covered_in_row >= STREAMING_AFTER_TICKS {
            set_timer_slack_ns(STREAMING_SLACK_NS);
            self.relaxed = true;
        }
    }

    /// A tick runs; returns whether the wait before it was relaxed. Precise from now on.
    fn tick_runs(&mut self) -> bool {
        self.covered_in_row = 0;
        let was = self.relaxed;
        if was {
            set_timer_slack_1ns();
            self.relaxed = false;
        }
        was
    }
}

/// Whether a report at `now_ns` (before `deadline_ns`) falls in the period that the tick at
/// `deadline_ns` closes, `(deadline - period, deadline]`; otherwise it falls in an earlier period,
/// whose tick an earlier report already covered (the deadline was moved past it).
fn covers_upcoming_tick(now_ns: u64, deadline_ns: u64, period_ns: u64) -> bool {
    deadline_ns - now_ns < period_ns
}

/// Starts the loop thread. It runs until `stop` is set, then returns the engine.
///
/// The loop wakes at absolute deadlines one period apart (`clock_nanosleep(TIMER_ABSTIME)`, or
/// `ppoll` on every hand source's ready descriptor with the time left) and runs
/// [`Engine::tick`] there. With a ready descriptor a report also wakes it between deadlines and
/// is published at once ([`Engine::device_ready`]); a tick whose period such a report already
/// covered has nothing to do and is skipped (unless a take or a field plays), so a device
/// reporting at the loop rate costs one wake-up per report, and the stream keeps its meaning:
/// every report in order, and a `held` frame for each period without one.
pub fn spawn_loop(
    mut engine: Engine,
    rate_hz: u32,
    priority: u8,
    stats: Arc<LoopStats>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<(thread::JoinHandle<Engine>, std::sync::mpsc::Receiver<String>)> {
    let (report_tx, report_rx) = std::sync::mpsc::channel();
    let handle = thread::Builder::new().name("frond-rt".into()).spawn(move || {
        let _ = report_tx.send(set_fifo(priority));
        drop(report_tx);
        set_timer_slack_1ns();
        let period = NS_PER_S / u64::from(rate_hz.max(1));
        let mut deadline = monotonic_ns() + period;
        // Device wakes in a row that found nothing to read. One can happen (a report rang the
        // doorbell but was read by the previous call); after a second the loop waits for the
        // deadline alone this period, so a descriptor that stays readable (hung up, say) cannot
        // spin it.
        let mut empty_wakes = 0u8;
        let mut precision = WaitPrecision::default();
        while !stop.load(Relaxed) {
            let fds: &mut [libc::pollfd] = if empty_wakes >= 2 { &mut [] } else { engine.ready_fds() };
            let woke = if fds.is_empty() {
                sleep_until_ns(deadline);
                Woke::Deadline
            } else {
                wait_any_readable_until_ns(fds, deadline)
            };
            let now = monotonic_ns();
            if woke == Woke::Readable {
                stats.device_wakes.fetch_add(1, Relaxed);
                if engine.device_ready(now) == 0 {
                    empty_wakes += 1;
                } else {
                    empty_wakes = 0;
                    if now < deadline && !engine.needs_every_tick() {
                        // The upcoming tick would find the report and do nothing else: cover it
                        // and wait for the next one. (A report in an already covered period
                        // only must not count for the upcoming tick.)
                        let upcoming = covers_upcoming_tick(now, deadline, period);
                        engine.cover_tick(upcoming);
                        if upcoming {
                            deadline += period;
                            precision.covered(engine.needs_every_tick());
                        }
                    }
                }
                continue;
            }
            empty_wakes = 0;
            let relaxed = precision.tick_runs();
            if !relaxed {
                stats.lateness.record(now.saturating_sub(deadline));
            }
            engine.tick(now);
            deadline += period;
            if relaxed {
                // The source fell silent during a relaxed wait: a held frame for every period
                // slept through, at once, as the stream promises one per period.
                let mut caught_up = 0;
                while deadline <= now && caught_up < MAX_CATCH_UP_TICKS {
                    engine.tick(now);
                    deadline += period;
                    caught_up += 1;
                }
            }
            let after = monotonic_ns();
            if after >= deadline + period {
                // More than a whole period behind: skip the missed deadlines instead of
                // bursting through them, and count it.
                let missed = (after - deadline) / period;
                deadline += missed * period;
                stats.overruns.fetch_add(1, Relaxed);
            }
        }
        engine
    })?;
    Ok((handle, report_rx))
}

#[cfg(test)]
mod tests {
    use super::{STREAMING_AFTER_TICKS, STREAMING_SLACK_NS, WaitPrecision, covers_upcoming_tick};

    fn timer_slack_ns() -> u64 {
        // SAFETY: PR_GET_TIMERSLACK takes no arguments and returns the calling thread's slack.
        unsafe { libc::prctl(libc::PR_GET_TIMERSLACK, 0, 0, 0, 0) as u64 }
    }

    /// The waits relax only after enough covered ticks in a row, never while the engine needs
    /// every tick, and every tick that runs makes them precise again (read back from the kernel).
    #[test]
    fn waits_relax_only_while_reports_cover_every_tick() {
        super::set_timer_slack_1ns();
        let mut p = WaitPrecision::default();
        for _ in 0..STREAMING_AFTER_TICKS - 1 {
            p.covered(false);
        }
        assert_eq!(timer_slack_ns(), 1, "not yet");
        p.covered(true);
        assert_eq!(timer_slack_ns(), 1, "a stage or a second hand needs every tick");
        p.covered(false);
        assert_eq!(timer_slack_ns(), STREAMING_SLACK_NS);
        assert!(p.tick_runs(), "the tick after a relaxed wait knows it");
        assert_eq!(timer_slack_ns(), 1);
        assert!(!p.tick_runs());
        p.covered(false);
        assert_eq!(timer_slack_ns(), 1, "the count starts again after a tick");
    }

    #[test]
    fn a_report_covers_the_tick_that_closes_its_period() {
        // Ticks every 1000 ns; the next deadline is at 10_000.
        assert!(covers_upcoming_tick(9_001, 10_000, 1_000), "just after the previous tick");
        assert!(covers_upcoming_tick(9_999, 10_000, 1_000), "just before the deadline");
        // At exactly 9_000 the report belongs to the tick at 9_000 (its period is (8000, 9000]).
        assert!(!covers_upcoming_tick(9_000, 10_000, 1_000));
        // The deadline was already moved one period ahead by an earlier report: a second report
        // in that same earlier period does not cover the tick at 10_000.
        assert!(!covers_upcoming_tick(8_500, 10_000, 1_000));
    }
}
