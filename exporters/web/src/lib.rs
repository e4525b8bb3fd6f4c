//! The HTTP side of frond's browser pages (`frond-console`, `frond-warp serve`): one mechanism
//! for every page, so that a rule holds for all of them.
//!
//! A browser is hostile ground: any page the operator visits can make it send requests to
//! loopback. So:
//! - [`http`]: the request is read bounded (head, headers, body) and whole within one deadline;
//!   duplicate `Host`/`Origin` are refused; response heads carry only [`http::HeaderValue`]s,
//!   which no CR or LF from a request can become;
//! - [`access`]: who may use the page: on loopback, a `Host` that is a loopback literal with the
//!   listening port (no DNS rebinding); beyond loopback, the token; always, the page's own
//!   `Origin` for WebSockets and actions;
//! - [`gate`]: admission, so that slow or idle clients never lock the operator out;
//! - [`server`]: the accept loop that puts them together around a [`server::Site`];
//! - [`work`]: a bound on heavy work at once.

#![warn(missing_docs)]

pub mod access;
pub mod gate;
pub mod http;
pub mod server;
pub mod work;
