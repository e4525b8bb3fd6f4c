//! Issue 14, point 10: sockets belong to the daemon that made them. A daemon whose socket
//! directory was deleted (and re-created by a second daemon) notices and logs it, and on its way
//! out leaves the second daemon's sockets alone.

use std::process::{Command, Stdio};
use std::time::Duration;

use frond_e2e::{Daemon, Proc, bin, wait_for};

#[test]
fn a_daemon_whose_directory_was_replaced_leaves_the_new_daemons_sockets_alone() {
    let dir = tempfile::tempdir().unwrap();
    let socket_dir = dir.path().join("run");
    let log = dir.path().join("first.log");
    let child = Command::new(bin("frondd"))
        .args(["--source", "in-process", "--socket-dir"])
        .arg(&socket_dir)
        .arg("--takes-dir")
        .arg(dir.path().join("takes-first"))
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let mut first = Proc { child, name: "frondd (first)".into() };
    assert!(wait_for(Duration::from_secs(20), || socket_dir.join("control.sock").exists()));

    // The directory goes away under it, and a second daemon starts there.
    std::fs::remove_dir_all(&socket_dir).unwrap();
    let second = Daemon::start(dir.path(), &["--source", "in-process"]);
    assert_eq!(second.socket_dir, socket_dir);
    // The first one notices within its 1 s check and says so.
    assert!(
        wait_for(Duration::from_secs(5), || std::fs::read_to_string(&log)
            .unwrap()
            .contains("socket was removed or replaced")),
        "{}",
        std::fs::read_to_string(&log).unwrap()
    );

    // Stopping the first leaves the second's sockets in place, and the second answers.
    let status = first.terminate(Duration::from_secs(10)).expect("the first daemon stopped");
    assert!(status.success(), "{status:?}");
    assert!(socket_dir.join("control.sock").exists() && socket_dir.join("poses.sock").exists());
    assert!(second.status().ticks > 0);
    let log = std::fs::read_to_string(&log).unwrap();
    assert!(log.contains("left the socket alone"), "{log}");
}
