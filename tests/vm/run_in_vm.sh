#!/usr/bin/env bash
# Runs a command inside a small Linux VM that has SocketCAN, and exits with the command's status.
#
#   tests/vm/run_in_vm.sh WORK_DIR COMMAND [ARGS...]
#
# This machine's kernel has no AF_CAN, so the SocketCAN tests boot Debian's own kernel under QEMU
# (software emulation: the nested /dev/kvm here cannot boot it) with a busybox initramfs that loads
# the CAN, virtio-9p and vivid (virtual camera) modules, creates vcan0, shares the host's root
# read-only over 9p, and runs
# COMMAND chrooted into it (host binaries and can-utils run unchanged) in /var/tmp, a scratch
# tmpfs ($TMPDIR). The guest reports the
# status through QEMU's isa-debug-exit port. Everything comes from Debian's packages: the kernel
# package is downloaded into WORK_DIR once and unpacked there, never installed.
set -euo pipefail

work=$1
shift
mkdir -p "$work"
work=$(cd "$work" && pwd)

for tool in qemu-system-x86_64 busybox; do
  command -v "$tool" >/dev/null || { echo "run_in_vm: $tool is missing (scripts/install-deps.sh)" >&2; exit 2; }
done

# The kernel: the package linux-image-amd64 points at, fetched and unpacked once.
kernel_pkg=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-/{print $2; exit}')
[[ -n "$kernel_pkg" ]] || { echo "run_in_vm: cannot tell which linux-image package to use" >&2; exit 2; }
kroot=$work/$kernel_pkg
if [[ ! -d "$kroot/boot" ]]; then
  (cd "$work" && apt-get download "$kernel_pkg" >/dev/null 2>&1) ||
    { echo "run_in_vm: apt-get download $kernel_pkg failed" >&2; exit 2; }
  rm -rf "$kroot.tmp" && dpkg -x "$work/$kernel_pkg"_*.deb "$kroot.tmp" && mv "$kroot.tmp" "$kroot"
  rm -f "$work/$kernel_pkg"_*.deb
fi
version=$(ls "$kroot/lib/modules")
moddir=$kroot/lib/modules/$version
# Modules in dependency order. The package leaves modules.dep to depmod at install time, so read
# each module's own "depends=" from its .modinfo section.
declare -A path_of=()
while IFS= read -r ko; do
  base=${ko##*/}
  base=${base%.ko}
  path_of[${base//-/_}]=$ko
done < <(find "$moddir/kernel" -name '*.ko')
declare -A loaded=()
order=()
add_module() {
  local key=${1//-/_} dep ko
  [[ -n "${loaded[$key]:-}" ]] && return
  ko=${path_of[$key]:-}
  [[ -n "$ko" ]] || { echo "run_in_vm: module $1 not found" >&2; exit 2; }
  loaded[$key]=1
  for dep in $(strings -a "$ko" | sed -n 's/^depends=//p' | tr ',' ' '); do add_module "$dep"; done
  order+=("$ko")
}
# vivid: the kernel's virtual video driver, a camera at /dev/video0 for the V4L2 driver's test;
# virtio-gpu: QEMU's virtual GPU, a KMS device at /dev/dri/card0 for the display's.
for name in can can-raw can-dev vcan 9pnet_virtio 9p virtio_pci vivid virtio-gpu; do
  add_module "$name"
done

# The initramfs: busybox, the modules, and an init that runs the command.
initrd=$work/initrd-$version.cpio
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage"/{bin,proc,sys,dev,host,modules}
cp "$(command -v busybox)" "$stage/bin/busybox"
for m in "${order[@]}"; do cp "$m" "$stage/modules/"; done
printf '%s\n' "${order[@]##*/}" > "$stage/modules/order"
printf '%q ' "$@" > "$stage/command"
cat > "$stage/init" <<'INIT'
#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in $(cat /modules/order); do insmod /modules/$m || echo "vm: insmod $m failed"; done
ip link add dev vcan0 type vcan && ip link set vcan0 up
status=3
if mount -t 9p -o trans=virtio,version=9p2000.L,ro hostroot /host; then
  mount -t proc proc /host/proc 2>/dev/null
  mount -t sysfs sys /host/sys 2>/dev/null
  mount -t devtmpfs dev /host/dev 2>/dev/null
  # Scratch space on the read-only root: /var/tmp, not /tmp (the build may live under /tmp).
  mount -t tmpfs scratch /host/var/tmp
  chroot /host /bin/sh -c "cd /var/tmp && export TMPDIR=/var/tmp && $(cat /command)"
  status=$?
else
  echo "vm: cannot mount the host's root over 9p"
fi
echo "vm: command exited with status $status"
# isa-debug-exit: QEMU exits with (byte << 1) | 1. The byte is status + 1 (statuses above 125
# count as 125), so QEMU's own failures (status 1) never read as a guest's success.
[ "$status" -gt 125 ] && status=125
printf "\\$(printf '%03o' $((status + 1)))" | dd of=/dev/port bs=1 seek=244 count=1 2>/dev/null
poweroff -f
INIT
chmod +x "$stage/init"
(cd "$stage" && find . | busybox cpio -o -H newc 2>/dev/null) > "$initrd"

set +e
timeout 120 qemu-system-x86_64 -accel tcg -cpu max -machine pc -m 512 -smp 1 \
  -kernel "$kroot/boot/vmlinuz-$version" -initrd "$initrd" \
  -append "console=ttyS0 quiet panic=-1" \
  -fsdev local,id=hostroot,path=/,security_model=none,readonly=on,multidevs=remap \
  -device virtio-9p-pci,fsdev=hostroot,mount_tag=hostroot \
  -device isa-debug-exit,iobase=0xf4,iosize=0x04 -device virtio-gpu-pci \
  -nographic -no-reboot -nic none
qemu_status=$?
set -e
if ((qemu_status == 124)); then
  echo "run_in_vm: the VM did not finish within 120 s" >&2
  exit 1
fi
# ((status + 1) << 1) | 1 from the guest, so at least 3; anything else: the guest never reported.
if ((qemu_status % 2 == 1 && qemu_status >= 3)); then
  exit $(((qemu_status - 1) / 2 - 1))
fi
echo "run_in_vm: the guest stopped without reporting (qemu status $qemu_status)" >&2
exit 1
