#!/usr/bin/env python3
"""Charts of the camera tracker's accuracy on rendered views (docs/probe-tracking.md).

Reads what tests/unit/drivers/fiducial_accuracy_test.cpp leaves in <build>/fiducial_views/
(dodeca.csv and cube.csv: one row per view of the seeded random poses; a few of the views as
PNGs) and writes docs/images/fiducial-accuracy.png and docs/images/fiducial-views.png.

  build/ci/tests/unit/drivers/fiducial_accuracy_tests
  python3 scripts/plot_fiducial_accuracy.py build/ci/fiducial_views docs/images
"""
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def main():
    views, out = Path(sys.argv[1]), Path(sys.argv[2])
    dodeca, cube = rows(views / "dodeca.csv"), rows(views / "cube.csv")

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    for data, name, colour in ((dodeca, "dodecahedron", "tab:blue"), (cube, "cube", "tab:red")):
        tracked = [r for r in data if r["tracked"] == "1"]
        left.scatter([float(r["distance_mm"]) for r in tracked],
                     [float(r["rotation_error_deg"]) for r in tracked], s=10, color=colour,
                     label=f"{name} ({len(tracked)}/{len(data)} posed)")
        counts = [int(r["markers"]) for r in data]
        right.hist(counts, bins=[x - 0.5 for x in range(0, 9)], alpha=0.6, color=colour,
                   label=name)
    left.axhline(0.5, color="grey", linestyle="--", linewidth=1)
    left.set_xlabel("camera to body, mm")
    left.set_ylabel("rotation error, degrees (one frame, unfiltered)")
    left.set_title("160 random orientations, light, blur and noise")
    left.legend()
    right.axvline(2.5, color="grey", linestyle="--", linewidth=1)
    right.set_xlabel("markers the pose rests on")
    right.set_ylabel("views")
    right.set_title("markers seen per view (target: at least 3)")
    right.legend()
    fig.tight_layout()
    fig.savefig(out / "fiducial-accuracy.png", dpi=100)

    names = ["dodeca0", "dodeca1", "dodeca2", "dodeca-face-on0", "cube0", "cube-face-on0"]
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.4))
    for ax, name in zip(axes.flat, names):
        ax.imshow(mpimg.imread(views / f"{name}.png"), cmap="gray", vmin=0, vmax=1)
        ax.set_title(name)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(out / "fiducial-views.png", dpi=80)


if __name__ == "__main__":
    main()
