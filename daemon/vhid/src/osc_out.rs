//! [`OscGlove`]: the virtual glove sending `/frond/hand` OSC messages over UDP instead of HID
//! reports: the reference sender for frond's OSC input (`frond-vhid --osc HOST:PORT`), showing a
//! tracker bridge exactly what to send (one message per sample: `t` in seconds as a double, then
//! wrist pitch, yaw, roll and thumb g1, g2, g3 in degrees as floats). The glove's faults carry
//! over: dropped reports are not sent, a corrupted one goes out as bytes that are not OSC (the
//! daemon counts it as malformed), stalls and unplugs are silence, jitter delays, a clock jump
//! shifts `t`.

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;

use rosc::{OscMessage, OscPacket, OscType};

use crate::generator::{Generator, ReportSink, VhidError, VhidStats, VirtualGloveConfig, spawn_generator};
use crate::glove::REPORT_LEN;
use frond_device::profile::DeviceProfile;
use frond_device::report::ReportParser;
use frond_device::source::OSC_HAND_ADDRESS;

struct OscSink {
    socket: UdpSocket,
    target: SocketAddr,
    /// The glove's own reports, read back into samples (the same parser as the daemon's).
    parser: ReportParser,
}

impl ReportSink for OscSink {
    fn send(&mut self, report: &[u8; REPORT_LEN]) {
        let bytes = match self.parser.parse(report) {
            Ok(s) => {
                let h = s.raw;
                let mut args = vec![OscType::Double(s.device_time_us as f64 / 1e6)];
                args.extend(h.wrist_deg.iter().chain(&h.thumb_deg).map(|&a| OscType::Float(a)));
                let msg = OscPacket::Message(OscMessage { addr: OSC_HAND_ADDRESS.into(), args });
                match rosc::encoder::encode(&msg) {
                    Ok(b) => b,
                    Err(_) => return,
                }
            }
            // A corrupted report: what a broken bridge would send.
            Err(_) => report.to_vec(),
        };
        // UDP: a receiver that is not there yet is not an error of ours.
        let _ = self.socket.send_to(&bytes, self.target);
    }

    fn set_plugged(&mut self, _plugged: bool) {}
}

/// The virtual glove as an OSC sender.
pub struct OscGlove {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    stats: Arc<VhidStats>,
    local: SocketAddr,
}

impl OscGlove {
    /// Starts sending `config`'s samples to `target`.
    pub fn start(config: VirtualGloveConfig, target: SocketAddr) -> Result<Self, VhidError> {
        let generator = Generator::prepare(&config)?;
        let bind: SocketAddr = if target.is_ipv6() { "[::]:0" } else { "0.0.0.0:0" }
            .parse()
            .map_err(|_| VhidError::Config("bind address".into()))?;
        let socket =
            UdpSocket::bind(bind).map_err(|e| VhidError::Config(format!("cannot open a UDP socket: {e}")))?;
        let local = socket.local_addr().map_err(|e| VhidError::Config(e.to_string()))?;
        let sink =
            Box::new(OscSink { socket, target, parser: ReportParser::new(&DeviceProfile::frond_glove()) });
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(VhidStats::default());
        let thread = spawn_generator(generator, sink, Arc::clone(&stop), Arc::clone(&stats))?;
        Ok(OscGlove { stop, thread: Some(thread), stats, local })
    }

    /// What the generator did so far.
    pub fn stats(&self) -> Arc<VhidStats> {
        Arc::clone(&self.stats)
    }

    /// The local address the messages come from.
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }
}

impl Drop for OscGlove {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
