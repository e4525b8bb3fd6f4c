//! End-to-end tests: real `frondd`, `frond` and `frond-vhid` processes.

mod demo;
mod hostile;
mod hostile_takes;
mod live_modes;
mod osc_input;
mod rt_syscalls;
mod slow_subscriber;
mod soak;
mod stage;
mod systemd;
mod take_tools;
mod tap_matches_map;
