//! frond's operator console (`frond-console`): one browser page with the plant live in 3D (the
//! daemon's rig as frond-gltf bakes it, driven by the live poses), the stage's health, and the
//! daemon's controls. An exporter like the others: it subscribes with `frond_sdk` (so it never
//! slows the daemon) and acts on the control socket with its own credentials.
//!
//! - [`access`]: who may use it (loopback by default; a token beyond; `Origin` checks), and
//!   [`http`], the bounded HTTP/1.1: `frond_web`'s, shared with `frond-warp serve`;
//! - [`actions`]: the page's control actions, as the requests `frond` sends;
//! - [`calibrate`]: the guided calibration, `frond calibrate`'s steps from the page;
//! - `daemon_link`: the one control connection that status reads and actions share;
//! - [`meadow`]: a running field's definition and frames passed on to the page, which
//!   evaluates and draws every plant;
//! - [`relay`]: the subscription, keeping each element's latest pose;
//! - [`scene`]: the rig's GLB and node map for the 3D view;
//! - [`server`]: the endpoints and the pose WebSocket at the display rate;
//! - [`takes`]: the takes panel's list, playback and downloads;
//! - [`warp_panel`]: the seed-001 warp preview, JPEG frames over a WebSocket.

#![warn(missing_docs)]

pub use frond_web::{access, http};
pub mod actions;
pub mod calibrate;
mod daemon_link;
pub mod meadow;
pub mod relay;
pub mod scene;
pub mod server;
pub mod takes;
pub mod warp_panel;

/// Sleeps until `*next + period` and moves `*next` there: a loop paced on absolute deadlines,
/// which skips ahead instead of catching up after an overrun.
pub(crate) fn pace(next: &mut std::time::Instant, period: std::time::Duration) {
    *next += period;
    let now = std::time::Instant::now();
    if *next > now {
        std::thread::sleep(*next - now);
    } else {
        *next = now;
    }
}
