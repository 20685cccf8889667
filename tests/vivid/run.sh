#!/usr/bin/env bash
# The V4L2 driver on a real kernel driver: boot a Debian kernel in qemu with vivid loaded and
# run the footscan-vivid test binary (src/main.rs) inside it. Exits with the test's exit code.
#
#   tests/vivid/run.sh [frames per resolution, default 120]
#
# Installs what it needs (Debian packages, only if missing), downloads the kernel package once
# into target/vivid/, builds the test binary statically (its own target dir, so the main build's
# flags are untouched), packs an initramfs (busybox, the media modules, the binary, /init) and
# boots it under TCG (KVM does not work on these machines). Environment: VIVID_TIMEOUT (s,
# default 600) bounds the VM run.
#
# Machine: `-M pc`. Debian 12's qemu 7.2 with `-M microvm` hangs this kernel right after
# "tsc: Marking TSC unstable" (no PIT/HPET reference under TCG), with or without pit=on.
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
cache=$root/target/vivid
mkdir -p "$cache"
frames=${1:-120}

sudo=""
[ "$(id -u)" -ne 0 ] && sudo="sudo"

# 1. Packages. --no-install-recommends: a plain install removed qemu-utils here.
packages=(qemu-system-x86 busybox-static kmod cpio)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "vivid: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# 2. The kernel: the package linux-image-amd64 depends on (linux-image-6.1.0-*-amd64).
kpkg=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
if [ -z "$kpkg" ]; then
  $sudo apt-get update -qq
  kpkg=$(apt-cache depends linux-image-amd64 | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
fi
[ -n "$kpkg" ] || { echo "vivid: cannot find the kernel package" >&2; exit 2; }
deb=$(ls "$cache/${kpkg}"_*.deb 2>/dev/null | head -n1 || true)
if [ -z "$deb" ]; then
  echo "vivid: downloading $kpkg"
  (cd "$cache" && apt-get download "$kpkg" 2>&1 | grep -v '^W: Download is performed unsandboxed' || true)
  deb=$(ls "$cache/${kpkg}"_*.deb 2>/dev/null | head -n1 || true)
  [ -n "$deb" ] || { echo "vivid: apt-get download $kpkg failed" >&2; exit 2; }
fi
kdir=$cache/kernel-$kpkg
if [ ! -d "$kdir/boot" ]; then
  rm -rf "$kdir.tmp"
  dpkg-deb -x "$deb" "$kdir.tmp"
  mv "$kdir.tmp" "$kdir"
fi
vmlinuz=$(ls "$kdir"/boot/vmlinuz-* | head -n1)

# 3. The static test binary.
echo "vivid: building the static test binary"
export PATH="$HOME/.cargo/bin:$PATH"
host=x86_64-unknown-linux-gnu
RUSTFLAGS='-C target-feature=+crt-static' CARGO_PROFILE_RELEASE_DEBUG=0 \
  cargo build --release --quiet --target "$host" --target-dir "$cache/cargo" -p footscan-vivid --bin vivid-test
bin=$cache/cargo/$host/release/vivid-test
if readelf -d "$bin" | grep -q NEEDED; then
  echo "vivid: $bin is not static" >&2
  exit 2
fi

# 4. The initramfs: busybox, the modules in load order, the binary, /init.
modules=(mc videodev videobuf2-common videobuf2-v4l2 rc-core cec v4l2-dv-timings v4l2-tpg
  videobuf2-memops videobuf2-dma-contig videobuf2-vmalloc vivid)
ird=$cache/initramfs
rm -rf "$ird"
mkdir -p "$ird"/{bin,dev,proc,sys,lib/modules}
cp /bin/busybox "$ird/bin/busybox"
for m in "${modules[@]}"; do
  f=$(find "$kdir/lib/modules" -name "$m.ko" -o -name "$m.ko.xz" | head -n1)
  [ -n "$f" ] || { echo "vivid: module $m not in $kpkg" >&2; exit 2; }
  case $f in
    *.xz) xz -dc "$f" >"$ird/lib/modules/$m.ko" ;;
    *) cp "$f" "$ird/lib/modules/$m.ko" ;;
  esac
done
cp "$bin" "$ird/vivid-test"
strip "$ird/vivid-test" 2>/dev/null || true
cat >"$ird/init" <<INIT
#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
echo "VIVID INIT uptime \$(cut -d' ' -f1 /proc/uptime) s"
for m in ${modules[*]}; do
  if [ \$m = vivid ]; then
    insmod /lib/modules/\$m.ko n_devs=1 node_types=0x101 || echo "VIVID insmod \$m failed"
  else
    insmod /lib/modules/\$m.ko || echo "VIVID insmod \$m failed"
  fi
done
i=0
while [ ! -e /dev/video1 ] && [ \$i -lt 50 ]; do sleep 0.1; i=\$((i + 1)); done
echo "VIVID MODULES uptime \$(cut -d' ' -f1 /proc/uptime) s"
/vivid-test $frames
echo "VIVID_EXIT=\$?"
poweroff -f
INIT
chmod +x "$ird/init"
(cd "$ird" && find . | cpio -o -H newc --quiet | gzip -1) >"$cache/initramfs.cpio.gz"

# 5. Boot. TCG on a loaded 2-core machine is slow: generous timeout.
log=$cache/console.log
echo "vivid: booting $(basename "$vmlinuz") under qemu (TCG)"
start=$(date +%s.%N)
set +e
timeout "${VIVID_TIMEOUT:-600}" qemu-system-x86_64 -accel tcg -M pc -m 512M -smp 1 \
  -net none -nographic -no-reboot \
  -kernel "$vmlinuz" -initrd "$cache/initramfs.cpio.gz" \
  -append "console=ttyS0 quiet loglevel=3 panic=-1" </dev/null 2>&1 | tr -d '\r' | tee "$log"
qrc=${PIPESTATUS[0]}
set -e
end=$(date +%s.%N)
wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.1f", b - a }')
rc=$(sed -n 's/^VIVID_EXIT=\([0-9]*\).*/\1/p' "$log" | tail -n1)
if [ -z "$rc" ]; then
  echo "vivid: no exit code from the VM (qemu exit $qrc after $wall s; 124 = timeout); console in $log" >&2
  exit 3
fi
boot=$(sed -n 's/.*VIVID INIT uptime \([0-9.]*\) s.*/\1/p' "$log" | tail -n1)
test_s=$(sed -n 's/^VIVID TIME test \([0-9.]*\) s.*/\1/p' "$log" | tail -n1)
compared=$(sed -n 's/.*; frames compared \([0-9]*\)$/\1/p' "$log" | awk '{ n += $1 } END { print n + 0 }')
echo "vivid: boot to /init ${boot:-?} s (guest clock), test ${test_s:-?} s, frames compared bit-exact $compared, qemu wall time $wall s"
echo "vivid: VM exit code $rc"
exit "$rc"
