//! The console's one subscription to the daemon: a thread reads every pose as fast as the daemon
//! sends them (so the daemon never waits on the console; if the console fell behind, the daemon
//! would drop frames for it alone and the SDK reports the gap) and keeps only the latest pose of
//! each element, with the daemon's hello and element table. Page connections read that state at
//! the display rate ([`Live::changed_since`]), so their cost does not grow with the loop rate.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use frond_sdk::{ElementId, Event, Hello, Pose, Subscriber};

/// Most elements whose latest pose is kept: the rig's, the live stages', and a field's announced
/// plants (at most [`frond_protocol::field::MAX_ANNOUNCED_PLANTS`] each; the rest of a field is
/// drawn from its definition, not kept as poses).
pub const MAX_ELEMENTS: usize = 1024;

/// What the subscription knows, shared with the page connections.
#[derive(Debug, Default)]
pub struct LiveState {
    /// Whether the daemon is connected now.
    pub connected: bool,
    /// The daemon's hello, with its element table brought up to date.
    pub hello: Option<Hello>,
    /// Bumped whenever `hello` or `connected` changes.
    pub version: u64,
    /// The latest pose of each element, by element id order of arrival.
    pub poses: Vec<Pose>,
    /// Poses received.
    pub frames: u64,
    /// Gaps reported by the SDK, and the frames missing in them.
    pub gaps: u64,
    /// Frames missing in all gaps.
    pub missing: u64,
    /// Poses of elements beyond [`MAX_ELEMENTS`], not kept.
    pub overflow: u64,
    /// Why the daemon is not connected, in words.
    pub why: String,
    /// When element 0's latest pose arrived.
    pub main_at: Option<Instant>,
    /// Delivery latency of the last poses (daemon publish to this console).
    pub latency: LatencyRing,
    /// Glove-to-console latency of the last fresh poses: the report's device time to its arrival
    /// here, kept only while the glove's clock is the host's `CLOCK_MONOTONIC` (the virtual
    /// gloves: `frond-vhid --clock monotonic`); another clock is its own and cannot be compared.
    pub glove: LatencyRing,
    /// Fresh poses whose device time was not within a second of the host's clock.
    pub glove_foreign: u64,
    /// The running fields and their latest frames, passed on to the page.
    pub fields: crate::meadow::FieldRelay,
}

/// Poses whose delivery latency is kept for the health panel.
pub const LATENCY_RING: usize = 2048;

/// The last [`LATENCY_RING`] latencies, microseconds.
#[derive(Debug, Clone, Default)]
pub struct LatencyRing {
    /// The values, oldest overwritten first.
    pub values: Vec<u32>,
    next: usize,
}

impl LatencyRing {
    /// Keeps `v`, dropping the oldest once full.
    pub fn push(&mut self, v: u32) {
        if self.values.len() < LATENCY_RING {
            self.values.push(v);
        } else {
            self.values[self.next] = v;
        }
        self.next = (self.next + 1) % LATENCY_RING;
    }
}

/// `{"p50_us", "p99_us", "max_us", "samples", "histogram": [{"le_us", "count"}]}` of latencies
/// in microseconds (log-spaced buckets from 16 us to 1 s).
pub fn latency_json_of(values: &[u32]) -> serde_json::Value {
    let mut v = values.to_vec();
    v.sort_unstable();
    let q = |p: f64| v.get(((v.len() as f64 - 1.0) * p).round() as usize).copied();
    let mut histogram = Vec::new();
    let mut le = 16u32;
    let mut from = 0;
    while le <= 1_000_000 {
        let to = v.partition_point(|&x| x <= le);
        histogram.push(serde_json::json!({ "le_us": le, "count": to - from }));
        from = to;
        le *= 2;
    }
    histogram.push(serde_json::json!({ "le_us": null, "count": v.len() - from }));
    serde_json::json!({
        "p50_us": q(0.5), "p99_us": q(0.99), "max_us": v.last(), "samples": v.len(), "histogram": histogram,
    })
}

/// The shared state and the thread that fills it.
#[derive(Debug, Default)]
pub struct Live {
    state: Mutex<LiveState>,
}

impl Live {
    /// Empty state: not connected.
    pub fn new() -> Arc<Live> {
        let live = Live::default();
        live.lock().why = "connecting to the daemon".into();
        Arc::new(live)
    }

    /// The state (a poisoned lock is taken over: the state is plain data).
    pub fn lock(&self) -> MutexGuard<'_, LiveState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Copies into `out` the latest poses whose `seq` differs from the one in `sent` (element id
    /// -> last sent seq, updated), and returns the state version.
    pub fn changed_since(&self, sent: &mut Vec<(ElementId, u64)>, out: &mut Vec<Pose>) -> u64 {
        out.clear();
        let s = self.lock();
        for p in &s.poses {
            match sent.iter_mut().find(|(e, _)| *e == p.element) {
                Some((_, seq)) if *seq == p.seq => {}
                Some((_, seq)) => {
                    *seq = p.seq;
                    out.push(*p);
                }
                None => {
                    sent.push((p.element, p.seq));
                    out.push(*p);
                }
            }
        }
        s.version
    }

    /// Element 0's latest joint 0 (the root), if it arrived within `fresh`.
    pub fn root_pose(&self, fresh: Duration) -> Option<[f32; 3]> {
        let s = self.lock();
        let at = s.main_at?;
        if at.elapsed() > fresh || !s.connected {
            return None;
        }
        s.poses.iter().find(|p| p.element.is_global()).map(|p| p.joints_deg[0])
    }

    fn store(&self, pose: Pose) {
        let mut s = self.lock();
        s.frames += 1;
        if pose.element.is_global() {
            s.main_at = Some(Instant::now());
        }
        // Same machine, same clock: the pose's publish stamp to its arrival here.
        let now_ns = frond_sdk::clock::monotonic_ns();
        let latency = u32::try_from(now_ns.saturating_sub(pose.host_monotonic_ns) / 1000).unwrap_or(u32::MAX);
        s.latency.push(latency);
        // The report's device time (32-bit microseconds, wrapping) against the host's clock.
        if !pose.flags.contains(frond_sdk::PoseFlags::HELD) {
            let glove = ((now_ns / 1000) as u32).wrapping_sub(pose.device_time_us as u32);
            if glove < 1_000_000 {
                s.glove.push(glove);
            } else {
                s.glove_foreign += 1;
            }
        }
        if let Some(slot) = s.poses.iter_mut().find(|p| p.element == pose.element) {
            *slot = pose;
        } else if s.poses.len() < MAX_ELEMENTS {
            s.poses.push(pose);
        } else {
            s.overflow += 1;
        }
    }

    fn set_hello(&self, hello: Hello) {
        let mut s = self.lock();
        // Elements that are no longer announced keep no pose.
        s.poses.retain(|p| hello.elements.get(p.element).is_some() || p.element.is_global());
        s.hello = Some(hello);
        s.connected = true;
        s.why.clear();
        s.version += 1;
    }

    fn set_down(&self, why: String) {
        let mut s = self.lock();
        if s.connected || s.why != why {
            s.connected = false;
            s.why = why;
            s.version += 1;
        }
    }

    /// Subscribes to the daemon in `socket_dir` on a thread, reconnecting forever.
    pub fn spawn(self: &Arc<Live>, socket_dir: PathBuf) -> std::io::Result<std::thread::JoinHandle<()>> {
        let live = Arc::clone(self);
        std::thread::Builder::new().name("console-poses".into()).spawn(move || live.run(&socket_dir))
    }

    fn run(&self, socket_dir: &std::path::Path) {
        let retry = Duration::from_millis(250);
        loop {
            let opts = Subscriber::options()
                .give_up_after(None)
                .read_timeout(Some(Duration::from_millis(500)))
                .max_retry_interval(Duration::from_millis(500))
                .keep_field_frames(crate::meadow::FIELD_FRAME_RING);
            let mut sub = match opts.connect(socket_dir) {
                Ok(s) => s,
                Err(e) => {
                    self.set_down(e.to_string());
                    std::thread::sleep(retry);
                    continue;
                }
            };
            let mut hello = sub.hello().clone();
            self.set_hello(hello.clone());
            let (mut fields, mut update) = (Vec::new(), crate::meadow::FieldUpdate::default());
            loop {
                let event = sub.next_event();
                if crate::meadow::collect(&mut sub, &mut fields, &mut update) {
                    self.lock().fields.apply(&mut update);
                }
                match event {
                    Ok(Event::Pose(p)) => self.store(p),
                    Ok(Event::Gap { expected, got }) => {
                        let mut s = self.lock();
                        s.gaps += 1;
                        s.missing += got.saturating_sub(expected);
                    }
                    Ok(Event::RigChanged(h)) | Ok(Event::Reconnected(h)) => {
                        hello = h;
                        self.set_hello(hello.clone());
                    }
                    Ok(Event::Elements(table)) => {
                        hello.elements = table;
                        self.set_hello(hello.clone());
                    }
                    Ok(Event::Disconnected) => self.set_down("the daemon closed the pose stream".into()),
                    Err(frond_sdk::SdkError::Timeout { .. }) => {}
                    Err(e) => {
                        self.set_down(e.to_string());
                        std::thread::sleep(retry);
                        break;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(element: u16, seq: u64) -> Pose {
        Pose {
            seq,
            device_time_us: 0,
            host_monotonic_ns: 0,
            flags: Default::default(),
            element: ElementId::new(element),
            joints_deg: [[0.0; 3]; 4],
            hand: Default::default(),
        }
    }

    #[test]
    fn only_the_latest_new_pose_of_each_element_goes_out() {
        let live = Live::new();
        let (mut sent, mut out) = (Vec::new(), Vec::new());
        live.store(pose(0, 1));
        live.store(pose(0, 2));
        live.store(pose(3, 2));
        live.changed_since(&mut sent, &mut out);
        assert_eq!(out.iter().map(|p| (p.element.get(), p.seq)).collect::<Vec<_>>(), [(0, 2), (3, 2)]);
        live.changed_since(&mut sent, &mut out);
        assert!(out.is_empty(), "nothing new: nothing sent");
        live.store(pose(3, 5));
        live.changed_since(&mut sent, &mut out);
        assert_eq!(out.iter().map(|p| (p.element.get(), p.seq)).collect::<Vec<_>>(), [(3, 5)]);
        assert_eq!(live.lock().frames, 4);
    }

    #[test]
    fn latency_percentiles_and_histogram_come_from_the_kept_poses() {
        let values: Vec<u32> = (1..=100).map(|k| k * 10).collect(); // 10 .. 1000 us
        let j = latency_json_of(&values);
        assert_eq!(j["samples"], 100);
        assert_eq!(j["p50_us"], 510); // index round(99 * 0.5) = 50 -> 510
        assert_eq!(j["p99_us"], 990);
        assert_eq!(j["max_us"], 1000);
        let h = j["histogram"].as_array().unwrap();
        assert_eq!(h[0]["le_us"], 16);
        assert_eq!(h[0]["count"], 1, "10 us");
        assert_eq!(h[1]["count"], 2, "20, 30 us in (16, 32]");
        assert_eq!(h.iter().map(|b| b["count"].as_u64().unwrap()).sum::<u64>(), 100);
    }

    #[test]
    fn elements_beyond_the_bound_are_counted_not_kept() {
        let live = Live::new();
        for e in 0..(MAX_ELEMENTS as u16 + 5) {
            live.store(pose(e, 1));
        }
        let s = live.lock();
        assert_eq!((s.poses.len(), s.overflow), (MAX_ELEMENTS, 5));
    }
}
