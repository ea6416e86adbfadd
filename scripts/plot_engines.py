#!/usr/bin/env python3
"""Charts for docs/: the deformation methods' speed against accuracy, and the compression study.

  python3 scripts/plot_engines.py --bench engines.csv --compression exact.csv pcg.csv \
      --out docs/images

engines.csv: build/ci/tests/bench/engine_bench --benchmark_out=engines.csv
--benchmark_out_format=csv. Compression CSVs: ultrasim-kiosk --compression-study FILE --method M.
Needs python3-matplotlib (Debian); nothing in the build or the tests uses this script.
"""

import argparse
import csv
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METHOD_NAMES = {
    "pcg": "PCG FEM, 20 it. (published)",
    "msds-explicit": "MSDS explicit (published)",
    "exact": "exact FEM",
    "corotational": "corotational FEM, 20 it.",
    "msds-implicit": "MSDS implicit",
}


def read_bench(path):
    """Rows of the Google Benchmark CSV (after its preamble), with the name's arguments parsed."""
    lines = Path(path).read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("name,"))
    rows = []
    for row in csv.DictReader(lines[start:]):
        args = dict(re.findall(r"(\w+):(\d+)", row["name"]))
        if "method" not in args:
            continue
        row.update({k: int(v) for k, v in args.items()})
        rows.append(row)
    return rows


def pareto(rows, out_dir):
    fig, ax = plt.subplots(figsize=(7.5, 5))
    sizes = sorted({(r["nx"], r["ny"], r["nz"]) for r in rows})
    markers = dict(zip(sizes, "os^D"))
    for method in METHOD_NAMES:
        pts = [r for r in rows if r["label"] == method and r["threads"] == 1]
        if not pts:
            continue
        pts.sort(key=lambda r: r["nx"])
        xs = [float(r["real_time"]) for r in pts]
        ys = [max(float(r["error_vs_exact"]), 1e-7) for r in pts]
        line, = ax.plot(xs, ys, "-", alpha=0.6, label=METHOD_NAMES[method])
        for r, x, y in zip(pts, xs, ys):
            ax.plot(x, y, markers[(r["nx"], r["ny"], r["nz"])], color=line.get_color())
    for size, marker in markers.items():
        ax.plot([], [], marker, color="grey", label="%d×%d×%d nodes" % size)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ms per frame (1 thread)")
    ax.set_ylabel("displacement error vs exact FEM (max norm, relative)")
    ax.set_title("Deformation methods: time against error (exact FEM plotted at 1e-7)")
    ax.axvline(16.7, color="grey", lw=0.8, ls=":")
    ax.text(16.7, ax.get_ylim()[1], " 60 Hz frame", va="top", fontsize=8, color="grey")
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(True, which="both", alpha=0.2)
    fig.tight_layout()
    fig.savefig(out_dir / "engines-pareto.png", dpi=110)


def compression(paths, out_dir):
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for path in paths:
        text = Path(path).read_text().splitlines()
        method = text[0].split()[-1] if text[0].startswith("#") else Path(path).stem
        rows = [r for r in csv.DictReader(line for line in text if not line.startswith("#"))]
        rows = [r for r in rows if r["diverged"] == "0"]
        force = [float(r["force_n"]) for r in rows]
        vein0 = float(rows[0]["vein_area_mm2"])
        artery0 = float(rows[0]["artery_area_mm2"])
        line, = ax.plot(force, [float(r["vein_area_mm2"]) / vein0 for r in rows], "-",
                        label="vein, " + METHOD_NAMES.get(method, method))
        ax.plot(force, [float(r["artery_area_mm2"]) / artery0 for r in rows], "--",
                color=line.get_color(), label="artery, " + METHOD_NAMES.get(method, method))
    ax.axhline(0.1, color="grey", lw=0.8, ls=":")
    ax.axhline(0.8, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("probe force (N)")
    ax.set_ylabel("lumen area / rest")
    ax.set_title("Compression test on the default case (probe over vein and artery)")
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.2)
    fig.tight_layout()
    fig.savefig(out_dir / "compression.png", dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--bench", help="engine_bench CSV")
    parser.add_argument("--compression", nargs="*", default=[], help="compression study CSVs")
    parser.add_argument("--out", default="docs/images")
    args = parser.parse_args()
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    if args.bench:
        pareto(read_bench(args.bench), out_dir)
    if args.compression:
        compression(args.compression, out_dir)


if __name__ == "__main__":
    main()
