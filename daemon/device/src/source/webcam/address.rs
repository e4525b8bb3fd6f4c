//! [`WebcamAddress`]: `webcam[:CAMERA_OR_FILE][?hand=left|right]`, as configurations name a camera.

use frond_motion::hand_landmarks::Handedness;

/// The camera when none is named.
pub const DEFAULT_CAMERA: &str = "/dev/video0";
/// Longest camera or file name taken.
pub const MAX_INPUT_CHARS: usize = 1024;

/// `webcam[:CAMERA_OR_FILE][?hand=left|right]` parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WebcamAddress {
    /// A V4L2 device (`/dev/video0`), a camera index (`0`), or an image or video file played
    /// in a loop (tests, demos).
    pub input: String,
    /// The hand that drives the plant (default right).
    pub hand: Handedness,
}

impl WebcamAddress {
    /// Whether the input is a camera (a `/dev/` node or an index), not a file.
    pub fn is_camera(&self) -> bool {
        self.input.starts_with("/dev/")
            || (!self.input.is_empty() && self.input.bytes().all(|b| b.is_ascii_digit()))
    }

    /// `left` or `right`.
    pub fn hand_name(&self) -> &'static str {
        match self.hand {
            Handedness::Left => "left",
            Handedness::Right => "right",
        }
    }
}

/// A text that is no `webcam[:CAMERA_OR_FILE][?hand=left|right]`; each names the text given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WebcamAddressError {
    /// The text does not start with `webcam`.
    #[error("{0:?}: expected webcam[:DEVICE], e.g. webcam:/dev/video0")]
    NotWebcam(String),
    /// A query other than `hand=left` or `hand=right`.
    #[error("{address:?}: unknown option {option:?} (expected hand=left or hand=right)")]
    UnknownOption {
        /// The address given.
        address: String,
        /// The query after `?`.
        option: String,
    },
    /// An empty, overlong or control-character camera name.
    #[error(
        "{0:?}: the camera must be a /dev/videoN node, an index or a file name (at most 1024 characters)"
    )]
    BadInput(String),
}

impl std::str::FromStr for WebcamAddress {
    type Err = WebcamAddressError;

    fn from_str(s: &str) -> Result<Self, WebcamAddressError> {
        let rest = s.strip_prefix("webcam").ok_or_else(|| WebcamAddressError::NotWebcam(s.to_string()))?;
        let (input, query) = rest.split_once('?').unwrap_or((rest, ""));
        let input = match input {
            "" => DEFAULT_CAMERA,
            i => i.strip_prefix(':').ok_or_else(|| WebcamAddressError::NotWebcam(s.to_string()))?,
        };
        if input.is_empty() || input.chars().count() > MAX_INPUT_CHARS || input.chars().any(char::is_control)
        {
            return Err(WebcamAddressError::BadInput(s.to_string()));
        }
        let hand = match query {
            "" | "hand=right" => Handedness::Right,
            "hand=left" => Handedness::Left,
            option => {
                return Err(WebcamAddressError::UnknownOption {
                    address: s.to_string(),
                    option: option.to_string(),
                });
            }
        };
        Ok(WebcamAddress { input: input.to_string(), hand })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn webcam_addresses_parse_and_say_what_is_wrong() {
        let a: WebcamAddress = "webcam".parse().unwrap();
        assert_eq!((a.input.as_str(), a.hand, a.is_camera()), ("/dev/video0", Handedness::Right, true));
        let a: WebcamAddress = "webcam:/dev/video2?hand=left".parse().unwrap();
        assert_eq!((a.input.as_str(), a.hand), ("/dev/video2", Handedness::Left));
        let a: WebcamAddress = "webcam?hand=left".parse().unwrap();
        assert_eq!((a.input.as_str(), a.hand_name()), ("/dev/video0", "left"));
        assert!("webcam:1".parse::<WebcamAddress>().unwrap().is_camera());
        let file: WebcamAddress = "webcam:/tmp/hand.mp4".parse().unwrap();
        assert!(!file.is_camera());
        assert_eq!(
            "webcam:/dev/video0?hand=both".parse::<WebcamAddress>().unwrap_err().to_string(),
            "\"webcam:/dev/video0?hand=both\": unknown option \"hand=both\" (expected hand=left or hand=right)"
        );
        assert!(matches!("webcam:".parse::<WebcamAddress>(), Err(WebcamAddressError::BadInput(_))));
        assert!(matches!("webcam:a\nb".parse::<WebcamAddress>(), Err(WebcamAddressError::BadInput(_))));
        assert!(matches!("webcamx".parse::<WebcamAddress>(), Err(WebcamAddressError::NotWebcam(_))));
    }
}
