//! A whole stage over Zenoh, for tools that follow every source of it (the stage recorder):
//! which sources it has now (the liveliness tokens of their bridges, `frond/<stage>/*/alive`)
//! and how each source's realtime clock compares with this host's (the bridge's `.../clock`
//! queryable, see [`crate::stage_time`]).

use std::time::{Duration, Instant};

use ::zenoh::Wait;

use crate::error::SdkError;
use crate::source::{KEY_ROOT, ZenohAddr, check_name};
use crate::stage_time::{ClockOffset, ClockReading, realtime_ns};
use crate::zenoh::{config, keys, open_session};

pub use crate::zenoh::MAX_STAGE_SOURCES;
/// Most clock exchanges one measurement makes.
pub const MAX_CLOCK_EXCHANGES: usize = 64;

/// A Zenoh session on one stage.
pub struct Stage {
    session: ::zenoh::Session,
    stage: String,
    /// How the session reaches the network (endpoints, configuration file); every source's
    /// address gets the same.
    template: ZenohAddr,
}

impl Stage {
    /// Opens a session on stage `stage`, reaching the network as `template` says (its key is
    /// ignored: endpoints and configuration file only).
    pub fn open(stage: &str, template: &ZenohAddr) -> Result<Stage, SdkError> {
        let name = format!("{KEY_ROOT}/{stage}");
        check_name("stage", stage)
            .map_err(|e| SdkError::Zenoh { source_key: name.clone(), reason: e.to_string() })?;
        let setup = |e: crate::zenoh::ZenohSetupError| SdkError::Zenoh {
            source_key: name.clone(),
            reason: e.to_string(),
        };
        let cfg = config(template.config.as_deref(), None, &template.connect, &template.listen, &[])
            .map_err(setup)?;
        let session = open_session(cfg).map_err(setup)?;
        Ok(Stage { session, stage: stage.to_owned(), template: template.clone() })
    }

    /// The stage's name.
    pub fn name(&self) -> &str {
        &self.stage
    }

    /// The stage's session, for the subscriptions and queries of its sources
    /// ([`crate::Subscriber::open_in_session`], [`crate::zenoh::query_statuses_in`]): one
    /// process, one session, so a configuration file that listens binds its port once.
    pub fn session(&self) -> &::zenoh::Session {
        &self.session
    }

    fn zerr(&self, e: ::zenoh::Error) -> SdkError {
        SdkError::Zenoh { source_key: format!("{KEY_ROOT}/{}", self.stage), reason: e.to_string() }
    }

    /// The sources whose bridges are connected to their daemons now, sorted; waits up to
    /// `timeout` for the tokens to arrive. Names that are not plain key chunks are skipped.
    pub fn sources(&self, timeout: Duration) -> Result<Vec<String>, SdkError> {
        let selector = format!("{KEY_ROOT}/{}/*/{}", self.stage, keys::ALIVE);
        let replies =
            self.session.liveliness().get(&selector).timeout(timeout).wait().map_err(|e| self.zerr(e))?;
        let mut found = Vec::new();
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else { continue };
            let mut chunks = sample.key_expr().as_str().split('/');
            let (Some(_root), Some(_stage), Some(source)) = (chunks.next(), chunks.next(), chunks.next())
            else {
                continue;
            };
            if check_name("source", source).is_ok() && !found.iter().any(|s: &String| s == source) {
                found.push(source.to_owned());
            }
            if found.len() >= MAX_STAGE_SOURCES {
                break;
            }
        }
        found.sort();
        Ok(found)
    }

    /// The address of `source` on this stage, reached like the stage.
    pub fn source_addr(&self, source: &str) -> Result<ZenohAddr, SdkError> {
        let mut addr = ZenohAddr::new(&self.stage, source).map_err(|e| SdkError::Zenoh {
            source_key: format!("{KEY_ROOT}/{}/{source}", self.stage),
            reason: e.to_string(),
        })?;
        addr.connect = self.template.connect.clone();
        addr.listen = self.template.listen.clone();
        addr.config = self.template.config.clone();
        Ok(addr)
    }

    /// How far `source`'s realtime clock is ahead of this host's: `exchanges` (1 to
    /// [`MAX_CLOCK_EXCHANGES`]) queries of its bridge's `.../clock`, the shortest round trip
    /// kept. Fails when no exchange succeeds within `timeout` overall.
    pub fn clock_offset(
        &self,
        source: &str,
        exchanges: usize,
        timeout: Duration,
    ) -> Result<ClockOffset, SdkError> {
        let key = keys::under(&format!("{KEY_ROOT}/{}/{source}", self.stage), keys::CLOCK);
        let deadline = Instant::now() + timeout;
        let mut samples = Vec::with_capacity(exchanges.clamp(1, MAX_CLOCK_EXCHANGES));
        while samples.len() < samples.capacity() && Instant::now() < deadline {
            let wait = deadline.saturating_duration_since(Instant::now()).max(Duration::from_millis(50));
            let sent = realtime_ns();
            let replies = self.session.get(&key).timeout(wait).wait().map_err(|e| self.zerr(e))?;
            let mut got = false;
            while let Ok(reply) = replies.recv() {
                let received = realtime_ns();
                let Ok(sample) = reply.result() else { continue };
                if let Some(reading) = ClockReading::from_json(&sample.payload().to_bytes())
                    && !got
                {
                    samples.push((sent, reading.unix_ns, received));
                    got = true;
                }
            }
            if !got {
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        ClockOffset::estimate(&samples).ok_or_else(|| {
            crate::zenoh::no_bridge(&self.session, key.trim_end_matches("/clock").to_owned(), timeout)
        })
    }
}
