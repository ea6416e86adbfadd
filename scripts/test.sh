#!/usr/bin/env bash
# Command (b): install what is missing, build everything (tests and benchmarks included) with
# warnings fatal, and run the whole test suite with ctest. .ci/run calls exactly this.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

scripts/install-deps.sh
cmake --preset ci >/dev/null
cmake --build --preset ci -j "$(nproc)"
ctest --preset ci -j "$(nproc)"
