#!/bin/bash
# Packs the kiosk for a timing run on a machine with a GPU but without this project's packages
# (the `device` tool's machines, docs/benchmarks.md "The kiosk on a GPU"): the ci build's objects
# linked --as-needed with probe_sources.cpp built without the camera probe sources, so that OpenCV
# and its ~300 MB of libraries are not loaded (the scripted probe of a headless run never uses
# them); the shared libraries the kiosk still loads (xz), the built cases, and Debian's glvnd EGL
# loader packages. Writes .gpu/ and .gl/ at the repository's root; list both in .git/info/exclude.
# Needs a ci build (scripts/test.sh or cmake --build --preset ci).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root/build/ci"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# probe_sources.cpp without the camera sources (they throw instead).
python3 - "$root/app/kiosk/src/probe_sources.cpp" "$work/probe_sources.cpp" <<'PY'
import sys
s = open(sys.argv[1]).read()
a = s.index('std::unique_ptr<hal::PoseSource> camera_tracker(')
s = s[:a] + s[s.index('}  // namespace\n\nconst char* probe_source_key'):]
a = s.index('    case hal::ProbeSourceKind::kCamera: {')
s = s[:a] + '''    case hal::ProbeSourceKind::kCamera:
    case hal::ProbeSourceKind::kCameraImages:
      throw std::invalid_argument("this timing build has no camera sources");
''' + s[s.index('    case hal::ProbeSourceKind::kKeyboard: {'):]
for include in ('camera/image_sequence', 'camera/v4l2_camera', 'fiducial/camera_pose_source'):
    s = s.replace('#include "ultrasim/drivers/%s.hpp"\n' % include, '')
open(sys.argv[2], 'w').write(s)
PY
compile=$(ninja -t commands app/kiosk/CMakeFiles/ultrasim_kiosk.dir/src/probe_sources.cpp.o | tail -1)
compile=$(sed "s# -MD -MT [^ ]* -MF [^ ]*##; s# -o [^ ]*probe_sources.cpp.o# -o $work/probe_sources.cpp.o#; s# -c [^ ]*probe_sources.cpp# -c $work/probe_sources.cpp#" <<<"$compile")
eval "$compile"
cp app/kiosk/libultrasim_kiosk.a "$work/libkiosk.a"
(cd "$work" && ar r libkiosk.a probe_sources.cpp.o)
link=$(ninja -t commands app/kiosk/ultrasim-kiosk | tail -1)
link=$(sed "s#app/kiosk/libultrasim_kiosk.a#$work/libkiosk.a#; s# -o app/kiosk/ultrasim-kiosk # -o $work/ultrasim-kiosk -Wl,--as-needed #" <<<"$link")
eval "$link"
libraries=$(ldd "$work/ultrasim-kiosk")
if grep -q opencv <<<"$libraries"; then
  echo "pack.sh: the timing build still loads OpenCV" >&2
  exit 1
fi

out="$root/.gpu"
rm -rf "$out" && mkdir -p "$out/lib" "$out/cases"
# The C library, the C++ runtime and the GL loaders come from the machine (the loaders from .gl).
for lib in $(ldd "$work/ultrasim-kiosk" | awk '$3 ~ /^\// {print $3}'); do
  case $(basename "$lib") in
    libc.so.* | libm.so.* | libpthread.so.* | libEGL.so.* | libGLESv2.so.* | libGLdispatch.so.* | \
      libgcc_s.so.* | libstdc++.so.*) ;;
    *) cp -L "$lib" "$out/lib/" ;;
  esac
done
(cd "$out" && tar cJf lib.tar.xz lib && rm -rf lib)
cp "$work/ultrasim-kiosk" "$out/" && strip "$out/ultrasim-kiosk"
cp -r cases/default cases/large cases/plus-spine "$out/cases/"
cp "$root/scripts/gpu_kiosk/run_on_device.sh" "$root/scripts/gpu_kiosk/summary.py" "$out/"

mkdir -p "$root/.gl" /tmp/amd64/partial
apt_options=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64)
apt-get "${apt_options[@]}" update >/dev/null
(cd "$root/.gl" && apt-get "${apt_options[@]}" download libegl1 libglvnd0 libgles2 libopengl0 \
  libgl1 libglx0 >/dev/null)
du -sh "$out" "$root/.gl"
