//! End-to-end tests: real `frondd`, `frond` and `frond-vhid` processes.

mod cli_habits;
mod console;
mod demo;
mod docs;
mod doctor;
#[path = "../support/field_socket.rs"]
mod field_socket;
mod gltf_live_field;
mod graph_play;
mod hands;
mod hostile;
mod hostile_files;
mod hostile_takes;
mod leap;
mod live_modes;
mod ltc;
mod meadow;
mod no_color;
mod osc_input;
mod osc_zenoh_field;
mod plausible;
#[path = "../support/python.rs"]
mod python;
mod rt_syscalls;
mod sdk_example;
mod slow_subscriber;
mod soak;
mod socket_dir;
mod stage;
mod stage_control;
mod stage_lossless;
mod stage_net;
mod stage_router;
mod structure;
mod systemd;
mod systemd_boot;
mod take_tools;
mod tap_matches_map;
mod timecode;
mod triggers;
mod untrusted_time;
mod warp_cage;
mod webcam;
mod webcam_calibrate;
mod zenoh;
mod zenoh_meadow;
