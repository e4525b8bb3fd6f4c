//! End-to-end tests: real `frondd`, `frond` and `frond-vhid` processes.

mod slow_subscriber;
mod tap_matches_map;
