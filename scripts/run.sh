#!/usr/bin/env bash
# Command (a): install what is missing, build, and run the kiosk headless on the embedded default
# case with a scripted probe that sweeps the case and presses. Writes B-scan and screen PNGs and a
# stats report into out/run-<UTC time>/ (or the folder given as the first argument).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release

out_dir=${1:-out/run-$(date -u +%Y%m%d-%H%M%S)}
build/release/app/kiosk/ultrasim-kiosk --headless \
  --case build/release/cases/default --script sweep-press --out "$out_dir"
echo "run: wrote $(cd "$out_dir" && pwd)"
