//! A webcam as a hand source: `webcam[:CAMERA_OR_FILE][?hand=left|right]` (issue 47).
//!
//! Files by responsibility: [`lines`] parses the landmark helper's output (pure, bounded),
//! `hub` runs the helper process for one camera and hands each hand's samples to its source,
//! `source` is the loop's side ([`WebcamSource`]).
//!
//! The helper, `frond-hands` (`daemon/device/webcam/frond_hands.py`, installed with
//! `daemon/device/webcam/install.sh`), reads the camera, runs MediaPipe Hands (the models ship in
//! the `mediapipe` 0.10.21 wheel: nothing is downloaded at run time) and writes one JSON line of
//! landmarks per frame on its stdout, a pipe only frondd holds. A thread of frondd reads the pipe
//! (each line bounded by [`lines::MAX_LINE_BYTES`], every value checked), turns the chosen
//! hand's world landmarks into a hand sample with [`frond_motion::hand_landmarks`] and queues it
//! for the loop, ringing a doorbell (the source's ready descriptor), as the Leap backend does.
//! Both hands of one camera (`?hand=left`, `?hand=right` as two `[[hands]]`) share one helper.
//! When the helper exits it is started again (after 1 s, backing off to 5 s); while it is away,
//! or the hand is out of view, no sample arrives and the loop flags frames held, then
//! `device_lost`, as for any stalled device.
//!
//! The helper is found as `$FROND_HANDS` (a path to the executable) or `frond-hands` on `PATH`.
//!
//! Given a directory (frondd gives its socket directory, which only its user and group may
//! enter), the helper also keeps the camera's preview picture there: `webcam-N.jpg`, the frame
//! with the hand's bones and landmarks drawn, replaced atomically a few times a second, mode
//! 0640. Each of the camera's sources names it in its status
//! ([`frond_protocol::CameraStatus::preview`]); the console's camera panel shows it.

pub mod address;
mod hub;
pub mod lines;
mod source;
#[cfg(test)]
mod tests;

pub use address::{WebcamAddress, WebcamAddressError};
pub use source::WebcamSource;

use super::spec::{Backend, SourceSpec, SpecError, SpecInput};

/// `webcam[:CAMERA_OR_FILE][?hand=left|right]`: hands seen by a camera.
pub(crate) const BACKEND: Backend = Backend { syntax: "webcam[:DEVICE]", parse };

fn parse(kind: &str, input: &SpecInput<'_>) -> Option<Result<SourceSpec, SpecError>> {
    let rest = kind.strip_prefix("webcam")?;
    (rest.is_empty() || rest.starts_with(':') || rest.starts_with('?')).then(|| {
        match kind.parse::<WebcamAddress>() {
            Ok(a) => Ok(SourceSpec::Webcam(a)),
            Err(problem) => Err(SpecError::BadWebcam { key: input.key.to_string(), problem }),
        }
    })
}
