#!/bin/bash
# A container for tests/e2e/systemd_boot.rs: boots the machine's own systemd as PID 1 of new PID,
# mount, UTS and IPC namespaces (`unshare --mount --pid --fork --uts --ipc` runs this script) on
# an overlay of / whose writes all go to a tmpfs, so nothing it or a unit does reaches the host's
# files (systemd cleans /tmp at boot, for one). Inside: the `frond` group made by the shipped
# systemd/frond.sysusers, the shipped frondd.service with ExecStart's /usr/bin/frondd pointed at
# the built binary, and an empty target to boot into. The network namespace is the host's, so a
# test's fake tracker on 127.0.0.1 is the service's loopback too.
# Usage: systemd_boot.sh WORKDIR REPO BINDIR   (WORKDIR: an empty directory, mounted over)
set -euo pipefail
W=$1; REPO=$2; BIN=$3
mount --make-rprivate /
mount -t tmpfs tmpfs "$W"
mkdir -p "$W/upper" "$W/work" "$W/root"
mount -t overlay overlay -o "lowerdir=/,upperdir=$W/upper,workdir=$W/work" "$W/root"
R=$W/root
mount --rbind /dev "$R/dev"
mount -t proc proc "$R/proc"
mount --rbind /sys "$R/sys"
mount -t tmpfs tmpfs "$R/run"
mount -t tmpfs tmpfs "$R/tmp"
# The repository and the binaries, read-only, wherever their file systems are.
for d in "$REPO" "$BIN"; do
    mkdir -p "$R$d"
    mount --bind "$d" "$R$d"
    mount -o remount,bind,ro "$R$d"
done
test -x "$R$BIN/frondd"
exec chroot "$R" /bin/bash -euc "
systemd-sysusers $REPO/systemd/frond.sysusers
sed 's|/usr/bin/frondd|$BIN/frondd|' $REPO/systemd/frondd.service > /etc/systemd/system/frondd.service
printf '[Unit]\nDescription=frond test target\n' > /etc/systemd/system/frondtest.target
# Whatever makes systemd start over (a SIGTERM to it re-executes it), it boots the same empty
# target, and never the units that touch devices: /dev is the host's.
ln -sf frondtest.target /etc/systemd/system/default.target
for unit in systemd-tmpfiles-setup.service systemd-tmpfiles-setup-dev.service \
            systemd-tmpfiles-setup-dev-early.service systemd-udevd.service systemd-udev-trigger.service \
            systemd-udev-settle.service systemd-modules-load.service systemd-sysctl.service; do
    ln -sf /dev/null /etc/systemd/system/\$unit
done
exec /lib/systemd/systemd --system --unit=frondtest.target
"
