//! `frond bench` measurements (in progress).
