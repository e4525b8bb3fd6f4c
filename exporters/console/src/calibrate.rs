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

use frond_formats::rig_toml::CalibrationText;
use frond_motion::calibrate::{Raw, STEPS, compute};
use frond_protocol::{ControlReply, ControlRequest, paths};
use frond_sdk::ControlClient;
use serde_json::{Value, json};

/// Poll period of the raw samples (about 50 Hz, as `frond calibrate`).
const POLL: Duration = Duration::from_millis(20);
/// Most samples kept per step (50 Hz for two minutes).
const MAX_STEP_SAMPLES: usize = 6000;

/// Shortest and longest recording of a step, seconds (`seconds_per_step`).
pub const SECONDS_PER_STEP: std::ops::RangeInclusive<f64> = 0.2..=120.0;

/// Why a calibration action cannot be done, with its HTTP status.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CalibrateError {
    /// A value of the request's body is wrong (400).
    #[error("{0}")]
    BadRequest(String),
    /// Not in the session's state: none running, a step being recorded, nothing measured (409).
    #[error("{0}")]
    Conflict(String),
    /// The daemon cannot be reached (502).
    #[error("the daemon: {0}")]
    Daemon(String),
    /// The console itself failed (500).
    #[error("{0}")]
    Internal(String),
}

impl CalibrateError {
    /// The HTTP status: a bad body is the page's to fix (400), the session's state a conflict
    /// (409, RFC 9110, section 15.5.10), an unreachable daemon a bad gateway (502).
    pub fn status(&self) -> u16 {
        match self {
            CalibrateError::BadRequest(_) => 400,
            CalibrateError::Conflict(_) => 409,
            CalibrateError::Daemon(_) => 502,
            CalibrateError::Internal(_) => 500,
        }
    }
}

/// The session a `start` body asks for: the user's name and each step's length. Every value is
/// checked, each problem named by its JSON key.
fn start_request(body: &Value) -> Result<(String, Duration), CalibrateError> {
    let bad = |m: String| CalibrateError::BadRequest(m);
    let user = body
        .get("user")
        .and_then(Value::as_str)
        .ok_or_else(|| bad("calibrate start needs {\"user\": \"...\"}".into()))?;
    paths::validate_take_name(user)
        .map_err(|e| bad(format!("user: {}", e.to_string().replace("take name", "user name"))))?;
    let range = || format!("between {} and {}", SECONDS_PER_STEP.start(), SECONDS_PER_STEP.end());
    let secs = match body.get("seconds_per_step") {
        None => 4.0,
        Some(v) => match v.as_f64() {
            Some(secs) if SECONDS_PER_STEP.contains(&secs) => secs,
            Some(secs) => return Err(bad(format!("seconds_per_step must be {}, got {secs}", range()))),
            None => {
                return Err(bad(format!(
                    "seconds_per_step must be a number of seconds {}, got {v}",
                    range()
                )));
            }
        },
    };
    Ok((user.to_string(), Duration::from_secs_f64(secs)))
}

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
    result: Option<Result<(String, Vec<String>), frond_motion::calibrate::CalibrateError>>,
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
    pub fn start(self: &Arc<Self>, socket_dir: PathBuf, body: &Value) -> Result<Value, CalibrateError> {
        let (user, step_len) = start_request(body)?;
        let mut control =
            ControlClient::connect(&socket_dir).map_err(|e| CalibrateError::Daemon(e.to_string()))?;
        let cancel = Arc::new(AtomicBool::new(false));
        let old = self.lock().replace(Session {
            user,
            step_len,
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
            .map_err(|e| CalibrateError::Internal(format!("cannot start polling the daemon: {e}")))?;
        Ok(self.state())
    }

    /// Records the next step.
    pub fn step(&self) -> Result<Value, CalibrateError> {
        let conflict = |m: &str| CalibrateError::Conflict(m.to_string());
        {
            let mut guard = self.lock();
            let s = guard.as_mut().ok_or_else(|| conflict("no calibration is running: start one first"))?;
            if s.recording.is_some() {
                return Err(conflict("a step is being recorded"));
            }
            let next = s.recorded.len();
            if next >= STEPS.len() {
                return Err(conflict("every step is recorded: apply the calibration or start again"));
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
    pub fn apply_request(&self) -> Result<ControlRequest, CalibrateError> {
        let guard = self.lock();
        let s = guard.as_ref().ok_or_else(|| CalibrateError::Conflict("no calibration is running".into()))?;
        match &s.result {
            Some(Ok((toml, _))) => {
                Ok(ControlRequest::SetCalibration { id: s.user.clone(), toml: toml.clone() })
            }
            Some(Err(e)) => Err(CalibrateError::Conflict(format!("the calibration failed: {e}"))),
            None => Err(CalibrateError::Conflict(format!(
                "{} of {} steps recorded",
                s.recorded.len(),
                STEPS.len()
            ))),
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
                Some(Err(e)) => json!({ "error": e.to_string() }),
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
fn finish(s: &Session) -> Result<(String, Vec<String>), frond_motion::calibrate::CalibrateError> {
    let r = &s.recorded;
    let m = compute(&s.user, &r[0], [&r[1], &r[2], &r[3]], &r[4])?;
    let text = format!(
        "# frond calibration for {:?}, measured by frond-console's guided calibration (section 5.4 of \"Interactive authoring of bending and twisting motions of short plants using hand gestures\")\n{}",
        s.user,
        m.calibration.to_toml_string()
    );
    Ok((text, m.warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A session that cannot start because of its body is the page's mistake (400), whatever
    /// the daemon's state; one the daemon's absence stops is a bad gateway (502).
    #[test]
    fn a_bad_start_body_is_a_bad_request_naming_its_key() {
        let c = Arc::new(Calibrations::default());
        let nowhere = tempfile::tempdir().unwrap();
        for (body, key) in [
            (json!({"user": "ann", "seconds_per_step": 0.0}), "seconds_per_step"),
            (json!({"user": "ann", "seconds_per_step": -3}), "seconds_per_step"),
            (json!({"user": "ann", "seconds_per_step": 121}), "seconds_per_step"),
            (json!({"user": "ann", "seconds_per_step": "fast"}), "seconds_per_step"),
            (json!({"user": "../ann"}), "user"),
            (json!({"user": 7}), "user"),
            (json!({}), "user"),
        ] {
            let e = c.start(nowhere.path().to_path_buf(), &body).unwrap_err();
            assert_eq!(e.status(), 400, "{body}: {e}");
            assert!(e.to_string().contains(key), "{body}: {e}");
        }
        let e = c
            .start(nowhere.path().to_path_buf(), &json!({"user": "ann", "seconds_per_step": 2}))
            .unwrap_err();
        assert_eq!(e.status(), 502, "{e}");
        assert_eq!(
            start_request(&json!({"user": "ann", "seconds_per_step": 0.2})).unwrap().1,
            Duration::from_millis(200)
        );
        assert_eq!(start_request(&json!({"user": "ann"})).unwrap().1, Duration::from_secs(4));
    }

    #[test]
    fn actions_out_of_turn_are_conflicts() {
        let c = Calibrations::default();
        assert_eq!(c.step().unwrap_err().status(), 409);
        assert_eq!(c.apply_request().unwrap_err().status(), 409);
    }
}
