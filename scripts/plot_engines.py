#!/usr/bin/env python3
"""Charts for docs/: the deformation methods' speed against accuracy, and the compression study.

  python3 scripts/plot_engines.py --bench engines.csv --budget budget.csv \
      --compression exact.csv pcg.csv --stability DIR --out docs/images

engines.csv: build/ci/tests/bench/engine_bench --benchmark_out=engines.csv
--benchmark_out_format=csv; budget.csv: the same from engine_budget_bench (error against time
as each method's per-frame budget grows). Compression CSVs: ultrasim-kiosk --compression-study
FILE --method M. Stability: the folder build/ci/tests/bench/stability_map --out DIR wrote.
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
    fig, ax = plt.subplots(figsize=(9.5, 5))
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
    # Beside the axes: inside, it covers the exact FEM's points at the bottom left.
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(True, which="both", alpha=0.2)
    fig.tight_layout()
    fig.savefig(out_dir / "engines-pareto.png", dpi=110)


# engine_budget_bench's methods: name, what the budget counts, reference, and where the budget
# labels go (points): the two MSDS lines run side by side, so one is labelled above, one below.
BUDGET_METHODS = {
    "pcg": ("(a) PCG FEM", "PCG it.", "converged PCG FEM", (3, 3)),
    "msds-explicit": ("(b) MSDS explicit, 5 ms steps", "steps", "converged PCG FEM", (0, 5)),
    "corotational": ("(d) corotational FEM", "PCG it.", "converged corotational", (3, 3)),
    "msds-implicit": ("(e) MSDS implicit, 0.1 s a frame", "steps", "converged PCG FEM",
                      (0, -11)),
}
ERROR_FLOOR = 1e-7  # a converged point's error (0) is drawn here on the log axis


def budget_panel(ax, rows, column, ylabel):
    """One line per method: error in `column` against ms per frame, points labelled by budget."""
    for method, (name, unit, reference, label_offset) in BUDGET_METHODS.items():
        pts = sorted((r for r in rows if r["label"] == method and r["threads"] == 1),
                     key=lambda r: r["budget"])
        if not pts:
            continue
        xs = [float(r["real_time"]) for r in pts]
        ys = [max(float(r[column]), ERROR_FLOOR) for r in pts]
        line, = ax.plot(xs, ys, "o-", ms=4, label="%s (%s) vs %s" % (name, unit, reference))
        for r, x, y in zip(pts, xs, ys):
            ax.annotate(str(r["budget"]), (x, y), textcoords="offset points",
                        xytext=label_offset, ha="center" if label_offset[0] == 0 else "left",
                        fontsize=7, color=line.get_color())
    ax.set_xscale("log")
    ax.set_yscale("log")
    bottom, top = ax.get_ylim()
    ax.set_ylim(bottom, top * 2.5)  # room for the labels above the top line
    ax.set_xlabel("ms per frame (1 thread)")
    ax.set_ylabel(ylabel)
    ax.axvline(16.7, color="grey", lw=0.8, ls=":")
    ax.text(16.7, 0.02, " 60 Hz frame", transform=ax.get_xaxis_transform(), fontsize=8,
            color="grey")
    ax.grid(True, which="both", alpha=0.2)


def budget(rows, out_dir):
    """Error against ms per frame as each method's budget grows, max norm beside 2-norm."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5), sharex=True)
    budget_panel(axes[0], rows, "error", "displacement error, max norm (relative)")
    budget_panel(axes[1], rows, "error_l2", "displacement error, 2-norm over the field (relative)")
    axes[0].set_title("one node's error: jumps where a contact decision differs", fontsize=9)
    axes[1].set_title("the whole field's", fontsize=9)
    fig.suptitle("Error after 60 frames (press, slide) against time per frame as the budget "
                 "grows; 32×16×16 nodes; points labelled by PCG iterations or steps per frame",
                 fontsize=10)
    # Below the axes: the lines run through every corner of the plots.
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="lower center", ncol=2)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    fig.savefig(out_dir / "engines-budget.png", dpi=110)


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


# What an engine did about a divergence, worst first, with the colours the map draws them in.
RECOVERY_COLOURS = {
    "reset": ("reset to rest", "#c0392b"),
    "kept-last-good": ("frame refused, last good shape kept", "#e67e22"),
    "substepped": ("rescued by smaller steps", "#f1c40f"),
    "none": ("stable", "#27ae60"),
}


def read_rows(path):
    return list(csv.DictReader(Path(path).read_text().splitlines()))


def stability_time_step(ax, rows, method, title):
    pts = [r for r in rows if r["method"] == method]
    for recovery, (name, colour) in RECOVERY_COLOURS.items():
        sel = [r for r in pts if r["recovery"] == recovery]
        if sel:
            ax.scatter([float(r["muscle_kpa"]) for r in sel], [float(r["dt_s"]) for r in sel],
                       s=60, marker="s", color=colour, label=name)
    moduli = sorted({float(r["muscle_kpa"]) for r in pts})
    bound = {float(r["muscle_kpa"]): float(r["explicit_bound_dt_s"]) for r in pts}
    ax.plot(moduli, [bound[m] for m in moduli], "k-", lw=1,
            label="explicit bound (largest stiffness/mass)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("muscle modulus, kPa (fat 0.4×)")
    ax.set_ylabel("time step, s (physical masses)")
    ax.axhline(0.005, color="grey", lw=0.8, ls=":")
    ax.text(moduli[0], 0.005, "published 5 ms", va="bottom", fontsize=7, color="grey")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.2)


def stability_poisson(ax, rows):
    for method in ["pcg", "corotational", "msds-explicit", "msds-implicit"]:
        pts = sorted((r for r in rows if r["method"] == method), key=lambda r: float(r["nu"]))
        ax.plot([float(r["nu"]) for r in pts],
                [max(float(r["error_after_hold"]), ERROR_FLOOR) for r in pts], "o-", ms=4,
                label=METHOD_NAMES[method])
    ax.set_yscale("log")
    ax.set_xlabel("Poisson's ratio ν (every tissue)")
    ax.set_ylabel("error vs exact FEM at the same ν, after 40 frames held")
    ax.set_title("ν → 0.5: 20 PCG iterations fall behind as the stiffness locks;\n"
                 "the spring model has no ν at all", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.2)


def stability_depth(ax, rows):
    methods = ["pcg", "msds-explicit", "exact", "corotational", "msds-implicit", "hyperelastic"]
    colours = {"ok": "#27ae60", "inverted": "#8fd19e"}
    for y, method in enumerate(methods):
        for r in (r for r in rows if r["method"] == method):
            if r["finite"] != "1":
                colour = "black"
            elif r["recovery"] != "none":
                colour = RECOVERY_COLOURS[r["recovery"]][1]
            elif float(r["inverted_fraction"]) > 0:
                colour = colours["inverted"]
            else:
                colour = colours["ok"]
            ax.barh(y, 0.5, left=float(r["depth_mm"]) - 0.5, height=0.7, color=colour)
    ax.set_yticks(range(len(methods)))
    ax.set_yticklabels([METHOD_NAMES.get(m, m) for m in methods], fontsize=7)
    ax.axvline(45, color="black", lw=1, ls="--")
    ax.text(45, len(methods) - 0.4, " bottom of the tissue", fontsize=7)
    ax.set_xlabel("probe depth below the skin, mm (45 mm block, fixed at the bottom)")
    ax.set_title("A probe pushed through the tissue: light green, a few tets inverted (counted, "
                 "< 0.5 %)", fontsize=9)
    ax.set_xlim(0, 60)


def stability(folder, out_dir):
    folder = Path(folder)
    dt_rows = read_rows(folder / "stability-dt.csv")
    fig = plt.figure(figsize=(13, 9))
    grid = fig.add_gridspec(2, 3, height_ratios=[1, 0.8])
    stability_time_step(fig.add_subplot(grid[0, 0]), dt_rows, "msds-explicit",
                        "(b) explicit Euler MSDS: 20 steps a frame, pressing 2 mm")
    ax = fig.add_subplot(grid[0, 1])
    stability_time_step(ax, dt_rows, "msds-implicit", "(e) implicit Euler MSDS: the same runs")
    handles, labels = ax.get_legend_handles_labels()
    stability_poisson(fig.add_subplot(grid[0, 2]), read_rows(folder / "stability-nu.csv"))
    stability_depth(fig.add_subplot(grid[1, :]), read_rows(folder / "stability-depth.csv"))
    for recovery, (name, colour) in RECOVERY_COLOURS.items():
        if name not in labels:
            handles.append(plt.Rectangle((0, 0), 1, 1, color=colour))
            labels.append(name)
    fig.legend(handles, labels, fontsize=8, loc="lower center", ncol=5)
    fig.suptitle("Where each method fails, and what the engine does about it "
                 "(16×8×8 nodes, fat over muscle)", fontsize=11)
    fig.tight_layout(rect=(0, 0.04, 1, 0.97))
    fig.savefig(out_dir / "stability-map.png", dpi=110)


VARIANT_STYLES = {
    "selective": ("selective, overlap stiffness split", "-"),
    "springs-alone": ("selective, seam springs alone (no remembered loads, as published)",
                      (0, (8, 2, 1, 2))),
    "all": ("every sub-volume, overlap stiffness split", "--"),
    "published-overlap": ("selective, overlap at full stiffness (published)", ":"),
    "4-exchanges": ("selective, seams exchanged 4 times a frame", "-."),
    "coarse": ("selective, coarse correction", (0, (1, 1))),
    "coarse-4-exchanges": ("selective, coarse correction, 4 exchanges", (0, (5, 1, 1, 1, 1, 1))),
    "fine": ("selective, fine correction (20 CG iterations)", (0, (3, 1, 1, 1))),
}


def stitching_series(ax, rows, scenario, column, variants, log=False):
    colours = dict(zip(["pcg", "msds-explicit", "msds-implicit"],
                       ["#1f77b4", "#d62728", "#2ca02c"]))
    for method, colour in colours.items():
        for variant in variants:
            name, style = VARIANT_STYLES[variant]
            pts = [r for r in rows if r["scenario"] == scenario and r["method"] == method
                   and r["variant"] == variant]
            if not pts:
                continue
            values = [float(r[column]) for r in pts]
            if log:
                values = [max(v, ERROR_FLOOR) for v in values]
            ax.plot([int(r["frame"]) for r in pts], values, linestyle=style, color=colour,
                    lw=2.4 if variant == "fine" else 1.2,
                    label=f"{METHOD_NAMES.get(method, method)}: {name}")
    if log:
        ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.2)


def stitching(folder, out_dir):
    folder = Path(folder)
    rows = read_rows(folder / "stitch-frames.csv")
    fig, axes = plt.subplots(2, 3, figsize=(17, 11))
    pressed = [r for r in rows if r["scenario"] == "pressed"]
    hold = min(int(r["frame"]) for r in pressed if r["phase"] == "hold")
    slide = min(int(r["frame"]) for r in pressed if r["phase"] == "slide")
    all_variants = list(VARIANT_STYLES)
    stitching_series(axes[0, 0], rows, "pressed", "error", all_variants, log=True)
    stitching_series(axes[1, 0], rows, "pressed", "gap_mm", ["selective", "springs-alone"],
                     log=True)
    stitching_series(axes[0, 1], rows, "placed", "error", all_variants, log=True)
    stitching_series(axes[1, 1], rows, "placed", "gap_mm", ["selective", "springs-alone"],
                     log=True)
    stitching_series(axes[0, 2], rows, "pressed", "stepped", ["selective", "all"])
    for ax in (axes[0, 0], axes[1, 0], axes[0, 2]):
        ax.axvspan(slide, hold, color="grey", alpha=0.08)
        ax.axvline(hold, color="grey", lw=0.8)
        ax.set_xlabel(f"frame: pressed 0-{slide}, slid across a seam {slide}-{hold}, then held")
    for ax in (axes[0, 1], axes[1, 1]):
        ax.set_xlabel("frame since the probe was put down where four sub-volumes meet")
    for ax in (axes[0, 0], axes[0, 1]):
        ax.axhline(0.02, color="black", lw=0.8, ls="--")
        ax.set_ylabel("stitched vs one piece, same method: max |Δu| / max |u|")
    axes[0, 1].axvline(10, color="black", lw=0.8, ls="--")
    axes[0, 0].set_title("Pressed and slid: the stick contact freezes the transient's "
                         "differences", fontsize=9)
    axes[0, 1].set_title("Placed and held: the error stitching itself leaves "
                         "(target ≤ 2 % after 10 frames)", fontsize=9)
    for ax in (axes[1, 0], axes[1, 1]):
        ax.axhline(0.1, color="black", lw=0.8, ls="--")
        ax.set_ylabel("largest gap between copies of a node, mm")
        ax.set_title("Seam gap before the midpoint display (target ≤ 0.1 mm); dash-dot: the "
                     "springs alone", fontsize=9)
    axes[0, 2].set_ylabel("sub-volumes stepped (of 25)")
    axes[0, 2].set_title("Selective: the touched, their neighbours and 1 more; the rest sleep",
                         fontsize=9)
    stiff = read_rows(folder / "stitch-stiffness.csv")
    ax = axes[1, 2]
    colours = dict(zip(["pcg", "msds-explicit", "msds-implicit"],
                       ["#1f77b4", "#d62728", "#2ca02c"]))
    for method, colour in colours.items():
        pts = sorted((r for r in stiff if r["method"] == method),
                     key=lambda r: float(r["stiffness_per_modulus_mm"]))
        if not pts:
            continue
        k = [float(r["stiffness_per_modulus_mm"]) for r in pts]
        ax.plot(k, [float(r["gap_mm"]) for r in pts], "o-", color=colour,
                label=f"{METHOD_NAMES.get(method, method)}: gap, mm")
        ax.plot(k, [float(r["error"]) for r in pts], "s--", color=colour,
                label=f"{METHOD_NAMES.get(method, method)}: error vs one piece")
    ax.axvline(20, color="grey", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("seam spring per unit modulus, mm (× E of the stiffest tet)\n"
                  "default 20; the implicit MSDS's 40, dotted")
    ax.axvline(40, color="#2ca02c", lw=0.8, ls=":")
    ax.set_title("Seam stiffness, placed scenario after 200 frames (every sub-volume)",
                 fontsize=9)
    ax.grid(True, which="both", alpha=0.2)
    ax.legend(fontsize=6)
    # One legend for the error panels, below them: 3 methods × 8 variants cover a panel.
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=3, frameon=False)
    fig.suptitle("The price of stitching: 25 sub-volumes of 12³ nodes against one 52×52×12 mesh, "
                 "published sphere probe, same method both sides", fontsize=11)
    fig.tight_layout(rect=(0, 0.13, 1, 0.97))
    fig.savefig(out_dir / "stitching-price.png", dpi=100)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--bench", help="engine_bench CSV")
    parser.add_argument("--budget", help="engine_budget_bench CSV")
    parser.add_argument("--compression", nargs="*", default=[], help="compression study CSVs")
    parser.add_argument("--stability", help="folder with stability_map's CSVs")
    parser.add_argument("--stitching", help="folder with stitch_price's CSVs")
    parser.add_argument("--out", default="docs/images")
    args = parser.parse_args()
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    if args.bench:
        pareto(read_bench(args.bench), out_dir)
    if args.budget:
        budget(read_bench(args.budget), out_dir)
    if args.compression:
        compression(args.compression, out_dir)
    if args.stability:
        stability(args.stability, out_dir)
    if args.stitching:
        stitching(args.stitching, out_dir)


if __name__ == "__main__":
    main()
