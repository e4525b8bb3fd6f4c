//! The console's guided calibration: the steps of `frond calibrate` (seed 000, section 5.4;
//! `frond_motion::calibrate`), started one by one from the page, each recording the daemon's raw
//! samples (`RawSample`, polled at 50 Hz on the control socket) for a few seconds, with the
//! live hand shown against the ranges measured so far; at the end the calibration, its warnings,
//! and a button to apply it to the daemon.
//!
//! `POST /api/calibrate/start {"user", "seconds_per_step"?}`, `POST /api/calibrate/step` (record
//! the next step), `GET /api/calibrate` (the session), `POST /api/calibrate/apply`,
//! `POST /api/calibrate/cancel`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use frond_motion::calibrate::{Raw, STEPS, compute};
use frond_protocol::{ControlReply, ControlRequest, paths};
use frond_sdk::ControlClient;
use serde_json::{Value, json};

/// Poll period of the raw samples (about 50 Hz, as `frond calibrate`).
const POLL: Duration = Duration::from_millis(20);
/// Most samples kept per step (50 Hz for two minutes).
const MAX_STEP_SAMPLES: usize = 6000;

/// One session.
#[derive(Debug)]
struct Session {
    user: String,
    step_len: Duration,
    recorded: Vec<Vec<Raw>>,
    /// The step being recorded and when it started.
    recording: Option<(usize, Instant)>,
    /// The latest raw sample and whether it was fresh.
    live: Option<(Raw, bool)>,
    /// The calibration's TOML text and warnings, or why it failed.
    result: Option<Result<(String, Vec<String>), String>>,
    /// Why polling the daemon failed, if it did.
    error: Option<String>,
    /// The session's poller: it stops when this is set or another session has replaced it.
    poller: Arc<AtomicBool>,
}

/// The console's calibration sessions (one at a time).
#[derive(Debug, Default)]
pub struct Calibrations {
    session: Mutex<Option<Session>>,
}

impl Calibrations {
    fn lock(&self) -> MutexGuard<'_, Option<Session>> {
        self.session.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Starts a session for `user` (replacing any), polling the daemon in `socket_dir`.
    pub fn start(self: &Arc<Self>, socket_dir: PathBuf, body: &Value) -> Result<Value, String> {
        let user =
            body.get("user").and_then(Value::as_str).ok_or("calibrate start needs {\"user\": \"...\"}")?;
        paths::validate_take_name(user).map_err(|e| e.to_string().replace("take name", "user name"))?;
        let secs = body.get("seconds_per_step").and_then(Value::as_f64).unwrap_or(4.0);
        if !(0.2..=120.0).contains(&secs) {
            return Err(format!("seconds_per_step must be between 0.2 and 120, got {secs}"));
        }
        let mut control = ControlClient::connect(&socket_dir).map_err(|e| e.to_string())?;
        let cancel = Arc::new(AtomicBool::new(false));
        let old = self.lock().replace(Session {
            user: user.to_string(),
            step_len: Duration::from_secs_f64(secs),
            recorded: Vec::new(),
            recording: None,
            live: None,
            result: None,
            error: None,
            poller: Arc::clone(&cancel),
        });
        if let Some(old) = old {
            old.poller.store(true, Ordering::Relaxed);
        }
        let me = Arc::clone(self);
        std::thread::Builder::new()
            .name("console-calibrate".into())
            .spawn(move || me.poll(&mut control, &cancel))
            .map_err(|e| e.to_string())?;
        Ok(self.state())
    }

    /// Records the next step.
    pub fn step(&self) -> Result<Value, String> {
        {
            let mut guard = self.lock();
            let s = guard.as_mut().ok_or("no calibration is running: start one first")?;
            if s.recording.is_some() {
                return Err("a step is being recorded".into());
            }
            let next = s.recorded.len();
            if next >= STEPS.len() {
                return Err("every step is recorded: apply the calibration or start again".into());
            }
            s.recorded.push(Vec::new());
            s.recording = Some((next, Instant::now()));
        }
        Ok(self.state())
    }

    /// Ends the session.
    pub fn cancel(&self) -> Value {
        if let Some(old) = self.lock().take() {
            old.poller.store(true, Ordering::Relaxed);
        }
        self.state()
    }

    /// The measured calibration as the request that applies it.
    pub fn apply_request(&self) -> Result<ControlRequest, String> {
        let guard = self.lock();
        let s = guard.as_ref().ok_or("no calibration is running")?;
        match &s.result {
            Some(Ok((toml, _))) => {
                Ok(ControlRequest::SetCalibration { id: s.user.clone(), toml: toml.clone() })
            }
            Some(Err(e)) => Err(format!("the calibration failed: {e}")),
            None => Err(format!("{} of {} steps recorded", s.recorded.len(), STEPS.len())),
        }
    }

    /// The session for the page: `{"running", "user", "steps": [{"name", "instruction",
    /// "samples", "wrist_mean", "thumb_mean", "wrist_min", "wrist_max", "thumb_max"}], "recording": {"step", "left_s"} | null,
    /// "live": {"wrist_deg", "thumb_deg", "fresh"} | null, "result": {"toml", "warnings"} |
    /// {"error"} | null}`.
    pub fn state(&self) -> Value {
        let guard = self.lock();
        let Some(s) = guard.as_ref() else {
            return json!({ "running": false, "steps": STEPS.iter().map(|(n, i)| json!({"name": n, "instruction": i})).collect::<Vec<_>>() });
        };
        let steps: Vec<Value> = STEPS
            .iter()
            .enumerate()
            .map(|(k, (name, instruction))| {
                let rec = s.recorded.get(k).map(Vec::as_slice).unwrap_or(&[]);
                let fold = |f: fn(&Raw) -> [f32; 3], init: f32, pick: fn(f32, f32) -> f32| {
                    (!rec.is_empty()).then(|| {
                        rec.iter().map(f).fold([init; 3], |a, v| std::array::from_fn(|i| pick(a[i], v[i])))
                    })
                };
                let mean = |f: fn(&Raw) -> [f32; 3]| {
                    (!rec.is_empty()).then(|| {
                        let sum = rec
                            .iter()
                            .map(f)
                            .fold([0.0f64; 3], |a, v| std::array::from_fn(|i| a[i] + f64::from(v[i])));
                        sum.map(|x| (x / rec.len() as f64) as f32)
                    })
                };
                json!({
                    "name": name, "instruction": instruction, "samples": rec.len(),
                    "wrist_mean": mean(|r| r.wrist_deg),
                    "thumb_mean": mean(|r| r.thumb_deg),
                    "wrist_min": fold(|r| r.wrist_deg, f32::MAX, f32::min),
                    "wrist_max": fold(|r| r.wrist_deg, f32::MIN, f32::max),
                    "thumb_max": fold(|r| r.thumb_deg, f32::MIN, f32::max),
                })
            })
            .collect();
        json!({
            "running": true,
            "user": s.user,
            "seconds_per_step": s.step_len.as_secs_f64(),
            "steps": steps,
            "recording": s.recording.map(|(k, at)| json!({ "step": k, "left_s": s.step_len.saturating_sub(at.elapsed()).as_secs_f64() })),
            "live": s.live.map(|(r, fresh)| json!({ "wrist_deg": r.wrist_deg, "thumb_deg": r.thumb_deg, "fresh": fresh })),
            "result": match &s.result {
                Some(Ok((toml, warnings))) => json!({ "toml": toml, "warnings": warnings }),
                Some(Err(e)) => json!({ "error": e }),
                None => Value::Null,
            },
            "error": s.error,
        })
    }

    fn poll(&self, control: &mut ControlClient, cancel: &Arc<AtomicBool>) {
        let mut next = Instant::now();
        while !cancel.load(Ordering::Relaxed) {
            let sample = control.request(&ControlRequest::RawSample);
            {
                let mut guard = self.lock();
                // Only this poller's own session (not one that replaced it).
                let Some(s) = guard.as_mut().filter(|s| Arc::ptr_eq(&s.poller, cancel)) else { return };
                match sample {
                    Ok(ControlReply::RawSample { t, wrist_deg, thumb_deg, fresh }) => {
                        let raw = Raw { t, wrist_deg, thumb_deg };
                        s.live = Some((raw, fresh));
                        s.error = None;
                        if let Some((k, at)) = s.recording {
                            let finite =
                                t.is_finite() && wrist_deg.iter().chain(&thumb_deg).all(|v| v.is_finite());
                            let step = &mut s.recorded[k];
                            let repeated = step.last().is_some_and(|r| r.t == t);
                            if fresh && finite && !repeated && step.len() < MAX_STEP_SAMPLES {
                                step.push(raw);
                            }
                            if at.elapsed() >= s.step_len {
                                s.recording = None;
                                if s.recorded[k].is_empty() {
                                    s.recorded.pop();
                                    s.error = Some(format!(
                                        "step {}: no fresh samples from the device; is the glove connected?",
                                        STEPS[k].0
                                    ));
                                } else if s.recorded.len() == STEPS.len() {
                                    s.result = Some(finish(s));
                                }
                            }
                        }
                    }
                    Ok(_) => s.error = Some("the daemon gave an unexpected reply to RawSample".into()),
                    Err(e) => s.error = Some(e.to_string()),
                }
            }
            crate::pace(&mut next, POLL);
        }
    }
}

/// The calibration of a session whose every step is recorded: its TOML (as `frond calibrate`
/// writes it) and warnings.
fn finish(s: &Session) -> Result<(String, Vec<String>), String> {
    let r = &s.recorded;
    let m = compute(&s.user, &r[0], [&r[1], &r[2], &r[3]], &r[4])?;
    let text = format!(
        "# frond calibration for {:?}, measured by frond-console's guided calibration (seed 000, section 5.4)\n{}",
        s.user,
        m.calibration.to_toml_string()
    );
    Ok((text, m.warnings))
}
