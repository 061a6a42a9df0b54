#!/usr/bin/env python3
"""Draws the nominal plant's hysteresis loops (θ_a against θ_d) at the paper's
four sheath angles, for CALIBRATION.md.

    .venv/bin/python tools/plot_loops.py [OUT.png]

Runs `fit_calibration loops` (the shipped defaults, the paper's input
25 sin(t) + 25 deg at 0.159 Hz, five periods, true angle) and plots its CSV.
Default output: crates/kflex-model/calibration_loops.png.
"""
import csv
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

ROOT = Path(__file__).resolve().parent.parent
PAPER_WIDTH = {0.0: 9.23, 90.0: 15.1, 180.0: 18.3, 270.0: 18.4}
PAPER_RMSE = {0.0: 7.84, 90.0: 9.95, 180.0: 16.6, 270.0: 21.9}


def traces(csv_path):
    out = {}
    with open(csv_path, newline="") as f:
        for row in csv.DictReader(f):
            s = float(row["sheath_deg"])
            d, a = out.setdefault(s, ([], []))
            d.append(float(row["theta_d_deg"]))
            a.append(float(row["theta_a_deg"]))
    return out


def plant_loops():
    """The nominal plant's traces per sheath angle: `fit_calibration loops`
    (the shipped defaults) read back as {sheath: (theta_d list, theta_a list)}."""
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "loops.csv"
        subprocess.run(
            ["cargo", "run", "--release", "--locked", "-q", "-p", "kflex-control",
             "--example", "fit_calibration", "--", "loops", str(data)],
            cwd=ROOT, check=True)
        return traces(data)


def main():
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "crates/kflex-model/calibration_loops.png"
    loops = plant_loops()
    fig, ax = plt.subplots(figsize=(6.4, 5.6), dpi=120)
    colours = {0.0: "#1b9e77", 90.0: "#d95f02", 180.0: "#7570b3", 270.0: "#e7298a"}
    for sheath, (d, a) in sorted(loops.items()):
        ax.plot(d, a, lw=1.2, color=colours.get(sheath),
                label=f"sheath {sheath:.0f}° (paper: RMSE {PAPER_RMSE[sheath]}°, width {PAPER_WIDTH[sheath]}°)")
    ax.plot([0, 50], [0, 50], ls="--", lw=0.8, color="0.5", label="θ_a = θ_d")
    ax.set_xlabel("command θ_d (deg)")
    ax.set_ylabel("joint angle θ_a (deg)")
    ax.set_title("kflex plant, shipped defaults: 25 sin(t) + 25 deg, 0.159 Hz, 5 periods")
    ax.set_xlim(-2, 52)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    tmp_png = target.with_suffix(".tmp.png")
    fig.savefig(tmp_png)
    tmp_png.replace(target)
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
