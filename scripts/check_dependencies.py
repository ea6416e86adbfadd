#!/usr/bin/env python3
"""Checks the dependency rules of DESIGN.md section 3 on includes and on the real link graph.

Usage:
  check_dependencies.py --source <repo root> [--build <configured build dir>] [--cmake <cmake>]
  check_dependencies.py --self-test

Include rules come from reading every C/C++ file under the module folders (hal/, drivers/<name>/,
render/, app/<module>/, config/, tests/). Link rules come from `cmake --graphviz` run on the build
directory, which regenerates the graph of the existing build tree without building anything.

Exit status: 0 when every rule holds (a one-line summary is printed), 1 when any is broken (one
line per violation, `file:line: rule`, paths relative to the source root), 2 when the check itself
could not run (bad arguments, cmake failing).

Python 3 standard library only: this runs in CI before anything is installed.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

# ---------------------------------------------------------------------------------------------
# The rules (DESIGN.md section 3). Change them together with the design map.

APP_MODULES = ("geometry", "sim", "imaging", "tracking", "sched", "kiosk", "tools")
SINGLE_MODULES = ("hal", "render", "config", "tests")  # folders at the top level
SETTINGS_OWNERS = {"sim", "imaging", "sched", "render", "geometry", "hal"}

# Modules each module may depend on (itself always allowed). "drivers" stands for any
# drivers/<name>; a driver may use hal only and never another driver.
ALLOWED = {
    "hal": set(),
    "drivers": {"hal"},
    "render": {"hal"},
    "geometry": set(),
    # app/sim is handed worker threads as a hal::JobSystem (DESIGN §3: "a job system is
    # injected"); it may include that one hal header and nothing else of hal (checked per header).
    "sim": {"geometry", "hal"},
    "imaging": {"geometry"},
    "tracking": {"hal"},
    "sched": {"hal"},
    # Includes: only the settings headers of these (checked per header); links: these modules.
    "config": set(SETTINGS_OWNERS),
    "kiosk": {"hal", "drivers", "render", "geometry", "sim", "imaging", "tracking", "sched",
              "config"},
    "tools": {"hal", "drivers", "render", "geometry", "sim", "imaging", "tracking", "sched",
              "config"},
    # "tests: anything; nothing depends on tests".
    "tests": {"hal", "drivers", "render", "geometry", "sim", "imaging", "tracking", "sched",
              "config", "kiosk", "tools"},
}

# app/* libraries and hal never touch the OS directly: time comes from an injected hal::Clock.
NO_OS_MODULES = {"hal", "geometry", "sim", "imaging", "tracking", "sched"}
OS_HEADER = re.compile(
    r"^(unistd\.h|fcntl\.h|time\.h|pthread\.h|poll\.h|gbm\.h|dlfcn\.h|dirent\.h|termios\.h|"
    r"semaphore\.h|sched\.h|xf86drm[^/]*\.h|"
    r"(sys|linux|net|netinet|arpa|EGL|GLES[^/]*|GL)/.*)$")
OS_CLOCK_TOKEN = re.compile(
    r"\b(steady_clock|system_clock|high_resolution_clock|utc_clock|tai_clock|gps_clock|"
    r"clock_gettime|gettimeofday)\b")
# app/sim: no I/O and no threads of its own (a job system is injected).
SIM_HAL_HEADERS = {"ultrasim/hal/job_system.hpp"}
SIM_FORBIDDEN_HEADERS = {"fstream", "iostream", "cstdio", "stdio.h", "thread", "future",
                         "filesystem"}

# app/geometry: std and Eigen only.
STD_HEADERS = set("""
algorithm any array atomic barrier bit bitset cassert ccomplex cctype cerrno cfenv cfloat charconv
chrono cinttypes ciso646 climits clocale cmath codecvt compare complex concepts condition_variable
coroutine csetjmp csignal cstdalign cstdarg cstdbool cstddef cstdint cstdio cstdlib cstring ctgmath
ctime cuchar cwchar cwctype deque exception execution expected filesystem flat_map flat_set format
forward_list fstream functional future generator initializer_list iomanip ios iosfwd iostream
istream iterator latch limits list locale map mdspan memory memory_resource mutex new numbers
numeric optional ostream print queue random ranges ratio regex scoped_allocator semaphore set
shared_mutex source_location span spanstream sstream stack stacktrace stdexcept stdfloat stop_token
streambuf string string_view strstream syncstream system_error thread tuple type_traits typeindex
typeinfo unordered_map unordered_set utility valarray variant vector version
""".split())
EIGEN_HEADER = re.compile(r"^(unsupported/)?Eigen/")

SOURCE_SUFFIXES = {".h", ".hh", ".hpp", ".hxx", ".inl", ".ipp", ".tpp", ".c", ".cc", ".cpp",
                   ".cxx"}

# Include spellings that name test code rather than a module header.
TEST_INCLUDE = re.compile(r"^(ultrasim/(tests|fakes|testing)/|tests/|fakes/)")


# ---------------------------------------------------------------------------------------------
# Modules


def module_folder(module: str) -> str:
    """Repository folder of a module name ("sim" -> "app/sim", "drivers/x" -> "drivers/x")."""
    if module in APP_MODULES:
        return f"app/{module}"
    return module


def module_of_path(rel: Path) -> str | None:
    """Module of a repository-relative path, or None outside every module folder."""
    parts = rel.parts
    if not parts:
        return None
    if parts[0] in SINGLE_MODULES:
        return parts[0]
    if parts[0] == "drivers" and len(parts) >= 3:
        return f"drivers/{parts[1]}"
    if parts[0] == "app" and len(parts) >= 3:
        return parts[1]  # may be unknown; reported by the caller
    return None


def kind(module: str) -> str:
    """The row of ALLOWED a module uses ("drivers/x" -> "drivers")."""
    return "drivers" if module.startswith("drivers/") else module


def known_module(module: str) -> bool:
    return kind(module) in ALLOWED


def edge_allowed(source: str, target: str) -> bool:
    if source == target:
        return True
    if kind(source) == "drivers" and kind(target) == "drivers":
        return False  # one driver reaches another only through hal
    return kind(target) in ALLOWED[kind(source)]


def edge_rule(source: str, target: str) -> str:
    if kind(target) == "tests":
        return "nothing outside tests/ may depend on tests"
    if kind(target) == "tools" and kind(source) != "tests":
        return "nothing may depend on app/tools (tools use modules, never the reverse)"
    if kind(source) == "drivers" and kind(target) == "drivers":
        return "a driver reaches another driver only through hal"
    allowed = sorted(ALLOWED[kind(source)])
    return f"{source} may depend on {', '.join(allowed) if allowed else 'no other module'}"


# ---------------------------------------------------------------------------------------------
# Reading sources


RAW_PREFIXES = ("", "u8", "u", "U", "L")


def identifier_before(text: str, i: int) -> str:
    """The run of identifier characters (or number digits) that ends just before text[i]."""
    j = i
    while j > 0 and (text[j - 1].isalnum() or text[j - 1] in "_'"):
        j -= 1
    return text[j:i]


def strip_code(text: str, keep_strings: bool) -> str:
    """Blanks comments (and, unless keep_strings, string and character literals), keeping every
    newline so that line numbers stay right."""
    out: list[str] = []
    i, n = 0, len(text)

    def blank(segment: str) -> str:
        return "".join("\n" if ch == "\n" else " " for ch in segment)

    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(blank(text[i:j]))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(blank(text[i:j]))
            i = j
        elif c == '"' or (text.startswith('R"', i) and identifier_before(text, i) in RAW_PREFIXES):
            start = i
            if c == "R":
                paren = text.find("(", i + 2)
                delimiter = text[i + 2:paren] if paren >= 0 else ""
                end = text.find(")" + delimiter + '"', paren if paren >= 0 else i)
                i = n if end < 0 else end + len(delimiter) + 2
            else:
                i += 1
                while i < n and text[i] != '"' and text[i] != "\n":
                    i += 2 if text[i] == "\\" else 1
                i = min(i + 1, n)
            out.append(text[start:i] if keep_strings else '""' + blank(text[start + 2:i]))
        elif c == "'" and not identifier_before(text, i)[:1].isdigit():
            # A character literal; a quote inside a number is a digit separator (16'667).
            start = i
            i += 1
            while i < n and text[i] != "'" and text[i] != "\n":
                i += 2 if text[i] == "\\" else 1
            i = min(i + 1, n)
            out.append(text[start:i] if keep_strings else "''" + blank(text[start + 2:i]))
        else:
            out.append(c)
            i += 1
    return "".join(out)


INCLUDE = re.compile(r'^[ \t]*#[ \t]*include[ \t]*([<"])([^>"\n]+)[>"]', re.MULTILINE)


@dataclass
class Include:
    line: int
    angled: bool
    name: str


def includes_of(text: str) -> list[Include]:
    code = strip_code(text, keep_strings=True)
    return [Include(code.count("\n", 0, m.start()) + 1, m.group(1) == "<", m.group(2).strip())
            for m in INCLUDE.finditer(code)]


def project_module_of_include(inc: Include, including_file: Path, source: Path) -> str | None:
    """The module a quoted include points into, or None for a third-party/system header."""
    if TEST_INCLUDE.match(inc.name):
        return "tests"
    if not inc.angled:
        # A path relative to the including file (e.g. "../../sim/src/x.hpp") belongs to the
        # module folder it resolves into.
        resolved = (including_file.parent / inc.name).resolve()
        try:
            rel = resolved.relative_to(source.resolve())
        except ValueError:
            rel = None
        if rel is not None and resolved.is_file():
            return module_of_path(rel)
    m = re.match(r"^ultrasim/(drivers/[^/]+|[^/]+)/", inc.name)
    if m:
        return m.group(1)
    return None


@dataclass
class Report:
    violations: list[tuple[str, int, str]] = field(default_factory=list)
    files: int = 0
    includes: int = 0
    project_includes: int = 0
    link_edges: int = 0
    link_targets: int = 0

    def add(self, file: str, line: int, rule: str) -> None:
        self.violations.append((file, line, rule))


def walk_sources(source: Path):
    roots = [source / name for name in ("hal", "render", "config", "tests")]
    roots += sorted(p for p in (source / "drivers").glob("*") if p.is_dir())
    roots += sorted(p for p in (source / "app").glob("*") if p.is_dir())
    for root in roots:
        if not root.is_dir():
            continue
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames[:] = sorted(d for d in dirnames
                                 if not d.startswith(".") and d != "__pycache__")
            for name in sorted(filenames):
                path = Path(dirpath) / name
                if path.suffix in SOURCE_SUFFIXES:
                    yield path


def settings_header(name: str) -> bool:
    base = name.rsplit("/", 1)[-1]
    return base == "settings.hpp" or base.endswith("_settings.hpp")


def check_file(path: Path, source: Path, report: Report) -> None:
    rel = path.relative_to(source)
    rel_text = rel.as_posix()
    module = module_of_path(rel)
    if module is None:
        return
    report.files += 1
    if not known_module(module):
        report.add(rel_text, 1, f"app/{module} is not a module of DESIGN.md section 3")
        return
    text = path.read_text(encoding="utf-8", errors="replace")

    for inc in includes_of(text):
        report.includes += 1
        target = project_module_of_include(inc, path, source)
        spelled = f'<{inc.name}>' if inc.angled else f'"{inc.name}"'
        if target is not None:
            report.project_includes += 1
            if not known_module(target):
                report.add(rel_text, inc.line,
                           f"{spelled}: ultrasim/{target} is not a module of DESIGN.md section 3")
            elif kind(module) == "config" and target != "config":
                if target not in SETTINGS_OWNERS or not settings_header(inc.name):
                    report.add(rel_text, inc.line,
                               f"{spelled}: config may include only the settings headers "
                               f"(settings.hpp, *_settings.hpp) of "
                               f"{', '.join(sorted(SETTINGS_OWNERS))}")
            elif kind(module) == "sim" and target == "hal" and inc.name not in SIM_HAL_HEADERS:
                report.add(rel_text, inc.line,
                           f"{spelled}: app/sim may include only {', '.join(sorted(SIM_HAL_HEADERS))}"
                           f" of hal (the injected job system)")
            elif not edge_allowed(module, target):
                report.add(rel_text, inc.line, f"{spelled}: {edge_rule(module, target)}")
            continue
        if kind(module) in NO_OS_MODULES and OS_HEADER.match(inc.name):
            report.add(rel_text, inc.line,
                       f"{spelled}: {module_folder(module)} may not use OS headers "
                       f"(inject hal interfaces instead)")
        elif kind(module) == "sim" and inc.name in SIM_FORBIDDEN_HEADERS:
            report.add(rel_text, inc.line,
                       f"{spelled}: app/sim does no I/O and starts no threads")
        elif (kind(module) == "geometry" and
              not (inc.angled and (inc.name in STD_HEADERS or EIGEN_HEADER.match(inc.name)))
              and not (not inc.angled and (path.parent / inc.name).is_file())):
            report.add(rel_text, inc.line, f"{spelled}: app/geometry may use only std and Eigen")

    if kind(module) in NO_OS_MODULES:
        code = strip_code(text, keep_strings=False)
        for m in OS_CLOCK_TOKEN.finditer(code):
            line = code.count("\n", 0, m.start()) + 1
            report.add(rel_text, line,
                       f"{m.group(1)}: {module_folder(module)} may not read the OS clock "
                       f"(take time from an injected hal::Clock)")


# ---------------------------------------------------------------------------------------------
# Link graph


DOT_NODE = re.compile(r'^\s*"(node\d+)"\s*\[\s*label\s*=\s*"((?:[^"\\]|\\.)*)"\s*,\s*'
                      r'shape\s*=\s*(\w+)')
DOT_EDGE = re.compile(r'^\s*"(node\d+)"\s*->\s*"(node\d+)"')


def parse_dot(text: str) -> tuple[dict[str, tuple[str, str]], list[tuple[str, str]]]:
    """Nodes (id -> (target name, shape)) and direct link edges (source id, target id)."""
    nodes: dict[str, tuple[str, str]] = {}
    edges: list[tuple[str, str]] = []
    for line in text.splitlines():
        m = DOT_NODE.match(line)
        if m:
            # The label is "name" or "name\n(alias)".
            nodes[m.group(1)] = (m.group(2).split("\\n", 1)[0], m.group(3))
            continue
        m = DOT_EDGE.match(line)
        if m:
            edges.append((m.group(1), m.group(2)))
    return nodes, edges


def target_folders(build: Path | None) -> dict[str, str]:
    """Target name -> repository folder it is defined in, from <build>/<folder>/CMakeFiles/
    <target>.dir (same layout for the Ninja and Makefile generators)."""
    folders: dict[str, str] = {}
    if build is None or not build.is_dir():
        return folders
    for dirpath, dirnames, _ in os.walk(build):
        if "CMakeFiles" in dirnames:
            rel = Path(dirpath).relative_to(build).as_posix()
            for entry in (Path(dirpath) / "CMakeFiles").iterdir():
                if entry.suffix == ".dir" and entry.is_dir():
                    folders.setdefault(entry.name[:-4], "" if rel == "." else rel)
        dirnames[:] = [d for d in dirnames if d not in ("CMakeFiles", "Testing", "_deps")]
    return folders


def module_of_target(name: str, shape: str, folders: dict[str, str]) -> str | None:
    """The module a CMake target belongs to; None for third-party and imported targets. The
    folder that defines it decides; the name is the fallback (interface libraries have no folder
    in the build tree)."""
    if "::" in name or name.startswith(("/", "-", "$")) or shape == "septagon":
        return None
    folder = folders.get(name)
    if folder is not None:
        module = module_of_path(Path(folder) / "CMakeLists.txt")
        if module is not None:
            return module
    elif shape in ("doubleoctagon", "tripleoctagon") and not name.startswith("ultrasim"):
        # A shared or module library built nowhere in this tree: a system package's imported
        # target without a namespace (OpenCV's opencv_core, ...). Ours are static.
        return None
    if re.match(r"^ultrasim_(tests?|fakes|testing)(_\w+)?$", name):
        return "tests"  # test support libraries
    m = re.match(r"^ultrasim_drivers_(\w+)$", name)
    if m:
        return f"drivers/{m.group(1)}"
    m = re.match(r"^ultrasim_([a-z]+)(_\w+)?$", name)
    if m:
        return m.group(1) if m.group(1) in ALLOWED else f"unknown:{name}"
    if name == "ultrasim" or name.startswith("ultrasim-"):
        # Executables: the kiosk binary, or a command-line tool.
        return "kiosk" if name in ("ultrasim", "ultrasim-kiosk") else "tools"
    return "tests"  # test executables, benchmarks and test helpers


def cmake_line(source: Path, folder: str, dependency: str) -> tuple[str, int]:
    """The CMakeLists.txt line naming dependency (or line 1) in folder, for messages."""
    cmakelists = Path(folder) / "CMakeLists.txt"
    alias = dependency.replace("ultrasim_", "ultrasim::", 1)
    try:
        lines = (source / cmakelists).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return cmakelists.as_posix(), 1
    for number, line in enumerate(lines, start=1):
        if re.search(rf"(?<![\w:-])({re.escape(dependency)}|{re.escape(alias)})(?![\w-])", line):
            return cmakelists.as_posix(), number
    return cmakelists.as_posix(), 1


def check_links(dot_text: str, source: Path, build: Path | None, report: Report) -> None:
    nodes, edges = parse_dot(dot_text)
    folders = target_folders(build)
    modules = {node: module_of_target(name, shape, folders) for node, (name, shape) in
               nodes.items()}
    seen_targets: set[str] = set()
    unknown_reported: set[str] = set()
    for a, b in edges:
        if a == b or a not in nodes or b not in nodes:
            continue
        source_module, target_module = modules[a], modules[b]
        if source_module is None or target_module is None:
            continue
        source_name, target_name = nodes[a][0], nodes[b][0]
        seen_targets.update((source_name, target_name))
        report.link_edges += 1
        folder = folders.get(source_name)
        if folder is None:
            folder = module_folder(source_module) if known_module(source_module) else "."
        file, line = cmake_line(source, folder, target_name)
        for module, name in ((source_module, source_name), (target_module, target_name)):
            if module.startswith("unknown:") and name not in unknown_reported:
                unknown_reported.add(name)
                report.add(file, line, f"target {name}: not a module of DESIGN.md section 3 "
                                       f"(name libraries ultrasim_<module>[_<part>])")
        if source_module.startswith("unknown:") or target_module.startswith("unknown:"):
            continue
        if not edge_allowed(source_module, target_module):
            report.add(file, line, f"{source_name} links {target_name}: "
                                   f"{edge_rule(source_module, target_module)}")
    report.link_targets = len(seen_targets)


def graphviz_of(build: Path, cmake: str) -> str:
    """Runs cmake --graphviz on the configured build tree and returns the main .dot text."""
    if not (build / "CMakeCache.txt").is_file():
        raise RuntimeError(f"{build} is not a configured CMake build directory")
    with tempfile.TemporaryDirectory(prefix="ultrasim-deps-") as tmp:
        dot = Path(tmp) / "deps.dot"
        result = subprocess.run([cmake, f"--graphviz={dot}", str(build)],
                                capture_output=True, text=True, check=False)
        if result.returncode != 0 or not dot.is_file():
            tail = (result.stderr or result.stdout).strip().splitlines()[-5:]
            raise RuntimeError("cmake --graphviz failed: " + " | ".join(tail))
        return dot.read_text(encoding="utf-8", errors="replace")


# ---------------------------------------------------------------------------------------------
# Driver


def run_checks(source: Path, build: Path | None, dot_text: str | None = None,
               cmake: str = "cmake") -> Report:
    report = Report()
    for path in walk_sources(source):
        check_file(path, source, report)
    if dot_text is None and build is not None:
        dot_text = graphviz_of(build, cmake)
    if dot_text is not None:
        check_links(dot_text, source, build, report)
    report.violations = sorted(set(report.violations))
    return report


def print_report(report: Report, links_checked: bool) -> int:
    for file, line, rule in report.violations:
        print(f"{file}:{line}: {rule}")
    links = (f"{report.link_edges} link edges between {report.link_targets} project targets"
             if links_checked else "no link graph (no --build given)")
    if report.violations:
        print(f"dependency rules: {len(report.violations)} violation(s) in {report.files} files, "
              f"{report.includes} includes, {links}", file=sys.stderr)
        return 1
    print(f"dependency rules: OK ({report.files} files, {report.includes} includes of which "
          f"{report.project_includes} project, {links})")
    return 0


def self_test() -> int:
    """Builds a tiny fake tree with known violations and checks that exactly those are found."""
    files = {
        # The two the design cares about most.
        "hal/include/ultrasim/hal/bad_os.hpp": "#pragma once\n#include <unistd.h>\n",
        "app/sim/src/bad_include.cpp": '#include <vector>\n#include "ultrasim/render/x.hpp"\n',
        # Clean files, with the forbidden words only in comments and strings.
        "app/sim/src/ok.cpp": ('#include "ultrasim/geometry/mesh.hpp"\n'
                               '#include <Eigen/Core>\n'
                               "// never std::chrono::steady_clock here\n"
                               "/* nor <unistd.h>\n   #include \"ultrasim/render/y.hpp\" */\n"
                               'const char* s = "gettimeofday";\n'
                               "long budget = 16'667; char q = '\"';\n"
                               'auto r = R"x(steady_clock)x";\n'),
        "hal/include/ultrasim/hal/clock.hpp": "#pragma once\n#include <atomic>\n",
        "config/src/ok.cpp": ('#include "ultrasim/sim/settings.hpp"\n'
                              '#include "ultrasim/render/settings.hpp"\n'
                              '#include "ultrasim/imaging/bscan_settings.hpp"\n'
                              "#include <toml++/toml.h>\n#include <fstream>\n"),
        "drivers/posix/src/clock.cpp": ('#include "ultrasim/hal/clock.hpp"\n#include <time.h>\n'
                                        "auto t = std::chrono::steady_clock::now();\n"),
        "app/kiosk/src/main.cpp": ('#include "ultrasim/drivers/posix/clock.hpp"\n'
                                   '#include "ultrasim/config/app_settings.hpp"\n'),
        "tests/unit/sim/x_test.cpp": ('#include "ultrasim/tools/report.hpp"\n'
                                      '#include "ultrasim/kiosk/session.hpp"\n#include <thread>\n'),
        "tests/fakes/fake_clock.hpp": "#pragma once\n",
        "app/tools/make_case/main.cpp": '#include "ultrasim/imaging/volume.hpp"\n',
        # More violations, one per rule.
        "app/sched/src/bad_clock.cpp": "auto t = std::chrono::steady_clock::now();\n",
        "config/src/bad.cpp": '#include "ultrasim/sim/fem.hpp"\n',
        "drivers/a/src/a.cpp": '#include "ultrasim/drivers/b/b.hpp"\n',
        "app/geometry/src/g.cpp": "#include <cmath>\n#include <zlib.h>\n",
        "render/src/r.cpp": '#include "ultrasim/tools/x.hpp"\n',
        "app/kiosk/src/bad.cpp": '#include "fakes/fake_clock.hpp"\n',
        "app/sim/src/io.cpp": "#include <fstream>\n",
        "app/sim/src/jobs.cpp": ('#include "ultrasim/hal/job_system.hpp"\n'
                                 '#include "ultrasim/hal/clock.hpp"\n'),
        "app/tracking/src/t.cpp": '#include "../../sim/src/io.cpp"\n',
        "app/sim/CMakeLists.txt": "ultrasim_add_library(sim PUBLIC_DEPS ultrasim::render)\n",
    }
    dot = "\n".join([
        'digraph "ultrasim" {',
        '    "node0" [ label = "ultrasim_sim\\n(ultrasim::sim)", shape = octagon ];',
        '    "node1" [ label = "ultrasim_render\\n(ultrasim::render)", shape = octagon ];',
        '    "node2" [ label = "ultrasim_kiosk\\n(ultrasim::kiosk)", shape = octagon ];',
        '    "node3" [ label = "ultrasim_config\\n(ultrasim::config)", shape = octagon ];',
        '    "node4" [ label = "ultrasim-make-case", shape = egg ];',
        '    "node5" [ label = "sim_tests", shape = egg ];',
        '    "node6" [ label = "Eigen3::Eigen", shape = pentagon ];',
        '    "node7" [ label = "ultrasim_fakes", shape = octagon ];',
        '    "node8" [ label = "ultrasim_drivers_posix\\n(ultrasim::drivers_posix)", '
        'shape = octagon ];',
        '    "node9" [ label = "ultrasim_hal\\n(ultrasim::hal)", shape = pentagon ];',
        '    "node0" -> "node1"  // ultrasim_sim -> ultrasim_render',
        '    "node0" -> "node6"  // ultrasim_sim -> Eigen3::Eigen',
        '    "node2" -> "node3"  // ultrasim_kiosk -> ultrasim_config',
        '    "node4" -> "node2" [ style = dotted ] // ultrasim-make-case -> ultrasim_kiosk',
        '    "node5" -> "node0" [ style = dotted ] // sim_tests -> ultrasim_sim',
        '    "node5" -> "node5"  // sim_tests -> sim_tests',
        '    "node1" -> "node7"  // ultrasim_render -> ultrasim_fakes',
        '    "node8" -> "node9"  // ultrasim_drivers_posix -> ultrasim_hal',
        '    "node3" -> "node0"  // ultrasim_config -> ultrasim_sim',
        '    "node11" [ label = "opencv_core", shape = doubleoctagon ];',
        '    "node8" -> "node11"  // ultrasim_drivers_posix -> opencv_core',
        '    "node10" [ label = "ultrasim_widgets", shape = octagon ];',
        '    "node2" -> "node10"  // ultrasim_kiosk -> ultrasim_widgets',
        '    "node0" -> "node10"  // ultrasim_sim -> ultrasim_widgets',
        "}",
    ])
    expected = [
        ("hal/include/ultrasim/hal/bad_os.hpp", 2, "<unistd.h>: hal may not use OS headers"),
        ("app/sim/src/bad_include.cpp", 2, '"ultrasim/render/x.hpp": sim may depend on geometry'),
        ("app/sched/src/bad_clock.cpp", 1, "steady_clock: app/sched may not read the OS clock"),
        ("config/src/bad.cpp", 1, '"ultrasim/sim/fem.hpp": config may include only the settings'),
        ("drivers/a/src/a.cpp", 1, "a driver reaches another driver only through hal"),
        ("app/geometry/src/g.cpp", 2, "<zlib.h>: app/geometry may use only std and Eigen"),
        ("render/src/r.cpp", 1, '"ultrasim/tools/x.hpp": nothing may depend on app/tools'),
        ("app/kiosk/src/bad.cpp", 1, '"fakes/fake_clock.hpp": nothing outside tests/ may depend'),
        ("app/sim/src/io.cpp", 1, "<fstream>: app/sim does no I/O and starts no threads"),
        ("app/sim/src/jobs.cpp", 2, "app/sim may include only ultrasim/hal/job_system.hpp"),
        ("app/tracking/src/t.cpp", 1, '"../../sim/src/io.cpp": tracking may depend on hal'),
        ("app/sim/CMakeLists.txt", 1, "ultrasim_sim links ultrasim_render: sim may depend on"),
        ("app/tools/CMakeLists.txt", 1, "ultrasim-make-case links ultrasim_kiosk: tools may"),
        ("render/CMakeLists.txt", 1, "ultrasim_render links ultrasim_fakes: nothing outside"),
        ("app/kiosk/CMakeLists.txt", 1, "target ultrasim_widgets: not a module"),  # once only
    ]
    with tempfile.TemporaryDirectory(prefix="ultrasim-deps-self-test-") as tmp:
        root = Path(tmp)
        for rel, text in files.items():
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_text(text, encoding="utf-8")
        report = run_checks(root, None, dot_text=dot)
    found = list(report.violations)
    problems = []
    for file, line, needle in expected:
        match = [v for v in found if v[0] == file and v[1] == line and needle in v[2]]
        if not match:
            problems.append(f"missed: {file}:{line}: ...{needle}...")
        for v in match:
            found.remove(v)
    problems += [f"unexpected: {file}:{line}: {rule}" for file, line, rule in found]
    if report.link_edges != 9:  # the external Eigen edge and the self edge are skipped
        problems.append(f"expected 9 project link edges, counted {report.link_edges}")
    if problems:
        print("check_dependencies self-test FAILED:")
        for p in problems:
            print("  " + p)
        return 1
    print(f"check_dependencies self-test: OK ({len(expected)} planted violations found, "
          f"no false alarms)")
    return 0


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", type=Path, help="repository root")
    parser.add_argument("--build", type=Path, help="configured build directory (link rules)")
    parser.add_argument("--cmake", default="cmake",
                        help="cmake executable to run --graphviz with (default: cmake on PATH)")
    parser.add_argument("--self-test", action="store_true", help="check the checker and exit")
    args = parser.parse_args(argv)
    if args.self_test:
        return self_test()
    if args.source is None:
        parser.error("--source is required (or --self-test)")
    source = args.source.resolve()
    build = args.build.resolve() if args.build is not None else None
    try:
        report = run_checks(source, build, cmake=args.cmake)
    except (RuntimeError, OSError) as error:
        print(f"check_dependencies: {error}", file=sys.stderr)
        return 2
    return print_report(report, links_checked=build is not None)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
