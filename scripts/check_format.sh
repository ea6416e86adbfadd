#!/usr/bin/env bash
# Fails, listing the files, when any C++ source in the repository differs from what clang-format
# makes of it with the repository's .clang-format. Fix with: scripts/check_format.sh --fix
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
mapfile -t files < <(git ls-files --cached --others --exclude-standard -- '*.cpp' '*.hpp' '*.h' |
                     while read -r f; do [[ -f "$f" ]] && echo "$f"; done)
if [[ "${1:-}" == "--fix" ]]; then
  clang-format -i "${files[@]}"
  exit 0
fi
# One clang-format run over every file; it names each file that differs in its warnings.
mapfile -t bad < <(clang-format --dry-run "${files[@]}" 2>&1 | sed -n 's/^\([^:]*\):[0-9]*:[0-9]*: warning:.*/\1/p' | sort -u)
if ((${#bad[@]})); then
  printf 'not clang-formatted: %s\n' "${bad[@]}"
  echo "fix with: scripts/check_format.sh --fix"
  exit 1
fi
echo "format: OK (${#files[@]} files)"
