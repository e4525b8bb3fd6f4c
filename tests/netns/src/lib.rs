//! Several "hosts" on one machine: Linux network namespaces joined by veth links to a switch
//! (a bridge device in a namespace of its own), so tests of frond on Zenoh run a daemon, its
//! bridge and remote subscribers as they would run on separate machines. Everything the test
//! creates lives in namespaces it made (named `frond<pid>-...`) and is deleted on drop, so no
//! traffic leaves them and nothing is left behind.

#![warn(missing_docs)]

use std::ffi::OsStr;
use std::net::Ipv4Addr;
use std::process::Command;

/// Why namespaces cannot be used here (not root, no `ip`), or `None` when they can.
pub fn unavailable() -> Option<String> {
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        return Some("network namespaces need root".into());
    }
    match Command::new("ip").arg("-V").output() {
        Ok(o) if o.status.success() => None,
        _ => Some("`ip` (iproute2) is missing: scripts/test installs it".into()),
    }
}

/// One host: a network namespace with an address on the stage's switch.
#[derive(Debug, Clone)]
pub struct Host {
    /// The namespace's name.
    pub ns: String,
    /// Its address on the switch (a /24).
    pub addr: Ipv4Addr,
    /// The switch's side of its link (set down to cut the host off).
    switch_port: String,
    switch_ns: String,
}

impl Host {
    /// `program` to run inside this host's namespace (`ip netns exec NS program`, which execs
    /// the program, so the child's pid is the program's).
    pub fn command(&self, program: impl AsRef<OsStr>) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", &self.ns]).arg(program);
        cmd
    }

    /// A Zenoh endpoint on this host's address.
    pub fn endpoint(&self, port: u16) -> String {
        format!("tcp/{}:{port}", self.addr)
    }

    /// Cuts this host's link (the switch's port goes down) or restores it.
    pub fn set_link(&self, up: bool) {
        ip(&["-n", &self.switch_ns, "link", "set", &self.switch_port, if up { "up" } else { "down" }]);
    }

    /// Runs `f` on a thread that has entered this host's namespace: sockets it creates (a UDP
    /// receiver, say) live on this host. Returns what `f` returns.
    pub fn run_inside<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> std::thread::JoinHandle<T> {
        let path = format!("/var/run/netns/{}", self.ns);
        std::thread::spawn(move || {
            let file = std::fs::File::open(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
            use std::os::fd::AsRawFd;
            // SAFETY: setns on a namespace file we hold open; it changes only this thread's
            // network namespace, which is what we want.
            let rc = unsafe { libc::setns(file.as_raw_fd(), libc::CLONE_NEWNET) };
            assert_eq!(rc, 0, "setns into {path}: {}", std::io::Error::last_os_error());
            f()
        })
    }
}

/// A switch and the hosts on it; all of it is deleted on drop.
pub struct Lan {
    /// The hosts, in the order asked for: addresses 10.N.0.1, 10.N.0.2, ...
    pub hosts: Vec<Host>,
    namespaces: Vec<String>,
}

impl Lan {
    /// Creates a switch and `n` hosts (up to 8) on it. Panics with the failing `ip` command.
    pub fn new(n: usize) -> Lan {
        assert!((1..=8).contains(&n), "1 to 8 hosts");
        let pid = std::process::id();
        let prefix = format!("frond{pid}");
        let switch_ns = format!("{prefix}-sw");
        let mut lan = Lan { hosts: Vec::new(), namespaces: Vec::new() };
        // A private subnet per test process, so parallel tests never share addresses.
        let net = 10 + (pid % 200) as u8;
        ip(&["netns", "add", &switch_ns]);
        lan.namespaces.push(switch_ns.clone());
        ip(&["-n", &switch_ns, "link", "add", "br0", "type", "bridge"]);
        ip(&["-n", &switch_ns, "link", "set", "br0", "up"]);
        for i in 0..n {
            let ns = format!("{prefix}-h{i}");
            ip(&["netns", "add", &ns]);
            lan.namespaces.push(ns.clone());
            let port = format!("p{i}");
            ip(&[
                "-n", &switch_ns, "link", "add", &port, "type", "veth", "peer", "name", "eth0", "netns", &ns,
            ]);
            ip(&["-n", &switch_ns, "link", "set", &port, "master", "br0", "up"]);
            let addr = Ipv4Addr::new(10, net, 0, i as u8 + 1);
            ip(&["-n", &ns, "addr", "add", &format!("{addr}/24"), "dev", "eth0"]);
            ip(&["-n", &ns, "link", "set", "eth0", "up"]);
            ip(&["-n", &ns, "link", "set", "lo", "up"]);
            lan.hosts.push(Host { ns, addr, switch_port: port, switch_ns: switch_ns.clone() });
        }
        lan
    }
}

impl Drop for Lan {
    fn drop(&mut self) {
        for ns in self.namespaces.iter().rev() {
            let _ = Command::new("ip").args(["netns", "delete", ns]).status();
        }
    }
}

fn ip(args: &[&str]) {
    let out = Command::new("ip").args(args).output().expect("run ip");
    assert!(out.status.success(), "ip {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim());
}
