#!/bin/bash
# Runs on the GPU machine (bash .gpu/run_on_device.sh, with .gpu and .gl carried; OUT set by
# the device tool): the packed kiosk (pack.sh) on two pinned cores, the GPU's EGL through glvnd,
# the large case under each stitched method, the default case, and the two soaks of
# docs/benchmarks.md. Writes summary.txt, three reports and two screens into $OUT.
cd "$(dirname "$0")/.."
for f in .gl/*.deb; do dpkg -x $f / >/dev/null; done; ldconfig
mkdir -p /tmp/gl && tar xJf .gpu/lib.tar.xz -C /tmp/gl && export LD_LIBRARY_PATH=/tmp/gl/lib
nv=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f $nv ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$nv
nvidia-smi -L; nproc; lscpu | grep -E "Model name|MHz" | head -3
ldd .gpu/ultrasim-kiosk | grep "not found"
K=.gpu/ultrasim-kiosk
C=.gpu/cases
S="${OUT:?the device tool sets OUT}/summary.txt"
summ() { python3 .gpu/summary.py "$1" "$2" >> "$S" 2>&1; }
run() { name=$1; shift; t0=$SECONDS; taskset -c 0,1 $K --headless "$@" --out /tmp/r_$name > /tmp/r_$name.log 2>&1; echo "$name rc $? wall $((SECONDS - t0)) s" >> "$S"; tail -3 /tmp/r_$name.log >> "$S"; summ $name /tmp/r_$name/report.json; }
# RUNS="large_pcg soak_large ..." runs those only (large_pcg always first: it checks the EGL).
want() { [ -z "${RUNS:-}" ] || [[ " $RUNS " == *" $1 "* ]]; }
run large_pcg --case $C/large --method pcg
grep -q llvmpipe /tmp/r_large_pcg/report.json && echo "SOFTWARE RENDERER" >> "$S"
if [ ! -f /tmp/r_large_pcg/report.json ]; then cat /tmp/r_large_pcg.log; cat "$S"; ls /usr/local/nvidia/share/glvnd/egl_vendor.d/ /usr/share/glvnd/egl_vendor.d/ 2>&1; exit 1; fi
want large_explicit && run large_explicit --case $C/large --method msds-explicit
want large_implicit && run large_implicit --case $C/large --method msds-implicit
want default_pcg && run default_pcg --case $C/default --method pcg
want soak_default && run soak_default --script soak --soak-seconds 120 --seed 11 --case $C/default --also-case $C/plus-spine
want soak_large && run soak_large --script soak --soak-seconds 60 --seed 5 --case $C/large
cp /tmp/r_large_pcg/report.json "$OUT"/large_pcg.json 2>/dev/null
cp /tmp/r_soak_default/report.json "$OUT"/soak_default.json 2>/dev/null
cp /tmp/r_soak_large/report.json "$OUT"/soak_large.json 2>/dev/null
ls /tmp/r_large_pcg/ | head; cp /tmp/r_large_pcg/screen-pressed.png "$OUT"/large-screen-pressed.png 2>/dev/null; cp /tmp/r_large_pcg/bscan-pressed.png "$OUT"/large-bscan-pressed.png 2>/dev/null
cat "$S"
