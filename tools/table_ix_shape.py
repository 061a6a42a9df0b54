#!/usr/bin/env python3
"""What loop shape Table IX's "none" row asks for, beside the plant's loops.

    .venv/bin/python tools/table_ix_shape.py

Table IX gives two numbers per sheath angle (RMSE, and the maximum
hysteresis read as the loop width); many loops share them. This script
finds the simplest family that reproduces both: a play (backlash) of
half-width b with a joint that rests at 0 and can only be lifted from it,

    p = play_b(θ_d),   θ_a = g · (max(p, b) − b),

so the rising branch starts 2b after the bottom reversal and climbs with
slope g, and the falling branch dwells 2b after the top reversal, then
comes down the line θ_a = g·θ_d. For each sheath angle it prints the
(2b, g) whose RMSE and width are closest to the paper's on the paper's
input (25 sin t + 25 deg, five periods), and beside them the same two
measures read off the plant's loops (`fit_calibration loops`, the shipped
defaults): the dead zone (command travelled after the bottom reversal
before θ_a has risen by 5 % of its range) and the rising branch's slope
(a straight-line fit over its middle half of θ_a).

A second block searches every play of slope g ≤ 1 that keeps θ_a ≥ 0,
with and without the dead zone at the bottom, and prints the largest RMSE
it can give at each width: a lag-type loop of the paper's width at 270 deg
reaches the paper's RMSE only with a long dead zone and a steep climb.
"""
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SHEATHS = [0.0, 90.0, 180.0, 270.0]
PAPER_RMSE = [7.84, 9.95, 16.6, 21.9]
PAPER_WIDTH = [9.23, 15.1, 18.3, 18.4]


def command(samples_per_period=4000, periods=5):
    t = np.linspace(0.0, 2 * np.pi * periods, samples_per_period * periods)
    return 25.0 * np.sin(t) + 25.0


def play(x, b):
    y = np.empty_like(x)
    p = 0.0
    for i, xi in enumerate(x):
        p = min(max(p, xi - b), xi + b)
        y[i] = p
    return y


def loop_width(x, y, periods=5):
    """Largest gap between the falling and the rising branch at equal command, last period."""
    n = len(x) // periods
    xs, ys = x[-n:], y[-n:]
    dx = np.gradient(xs)
    grid = np.linspace(1.0, 49.0, 400)
    branch = {}
    for name, sel in (("rise", dx > 0), ("fall", dx < 0)):
        order = np.argsort(xs[sel])
        branch[name] = np.interp(grid, xs[sel][order], ys[sel][order])
    return float(np.max(branch["fall"] - branch["rise"]))


def rmse(x, y, periods=5):
    # the plant's protocol measures every period; the play starts at rest, so
    # drop the first period's run-in
    n = len(x) // periods
    e = x[n:] - y[n:]
    return float(np.sqrt(np.mean(e * e)))


def best_play(x, plays, target_rmse, target_width):
    best = None
    for b, p in plays.items():
        lifted = np.maximum(p, b) - b
        for g in np.arange(0.3, 1.501, 0.05):
            y = g * lifted
            r, w = rmse(x, y), loop_width(x, y)
            cost = abs(r / target_rmse - 1) + abs(w / target_width - 1)
            if best is None or cost < best[0]:
                best = (cost, 2 * b, g, r, w)
    return best


def plant_loops():
    """The plant's loops (tools/plot_loops.py runs `fit_calibration loops`) as arrays."""
    sys.path.insert(0, str(ROOT / "tools"))
    from plot_loops import plant_loops as loops

    return {k: (np.array(d), np.array(a)) for k, (d, a) in loops().items()}


def plant_shape(d, a):
    """Dead zone after a bottom reversal in mid-run, and the rising branch's slope."""
    bottoms = [i for i in range(1, len(d) - 1) if d[i - 1] > d[i] <= d[i + 1]]
    i0 = min(bottoms, key=lambda i: abs(i - 0.4 * len(d)))
    i1 = i0 + 1
    while i1 < len(d) - 1 and d[i1 + 1] >= d[i1]:
        i1 += 1
    rd, ra = d[i0:i1 + 1], a[i0:i1 + 1]
    span = ra.max() - ra.min()
    moved = np.nonzero(ra > ra[0] + 0.05 * span)[0]
    dead = float(rd[moved[0]] - rd[0]) if len(moved) else float("nan")
    mid = (ra > ra.min() + 0.25 * span) & (ra < ra.min() + 0.75 * span)
    slope = float(np.polyfit(rd[mid], ra[mid], 1)[0]) if mid.sum() > 2 else float("nan")
    return dead, slope, float(span)


def main():
    x = command()
    plays = {b: play(x, b) for b in np.arange(0.0, 24.01, 0.5)}
    try:
        loops = plant_loops()
    except (OSError, subprocess.CalledProcessError) as e:
        print(f"could not run the plant ({e}); printing the paper's side only", file=sys.stderr)
        loops = {}
    print("| sheath (deg) | paper RMSE / width | play that gives them: dead zone 2b (deg), slope g, range | "
          "kflex: dead zone (deg), rising slope, range |")
    print("|---|---|---|---|")
    for s, r, w in zip(SHEATHS, PAPER_RMSE, PAPER_WIDTH):
        _, dz, g, pr, pw = best_play(x, plays, r, w)
        paper = f"{dz:.0f}, {g:.2f}, {g * (50 - dz):.1f} (RMSE {pr:.2f}, width {pw:.2f})"
        if s in loops:
            kd, ks, kr = plant_shape(*loops[s])
            ours = f"{kd:.1f}, {ks:.2f}, {kr:.1f}"
        else:
            ours = "-"
        print(f"| {s:.0f} | {r} / {w} | {paper} | {ours} |")

    print("\nLargest RMSE a lag-type loop (θ_a = g · play, g ≤ 1, θ_a ≥ 0) gives at a width of at least W:")
    print("| W (deg) | play from the command | play with the joint resting at 0 (as above) |")
    print("|---|---|---|")
    for width in (15.0, 18.4):
        best_plain = best_lifted = 0.0
        for b, p in plays.items():
            lifted = np.maximum(p, b) - b
            for g in np.arange(0.3, 1.001, 0.05):
                for y, which in ((g * np.maximum(p, 0.0), 0), (g * lifted, 1)):
                    if loop_width(x, y) >= width:
                        r = rmse(x, y)
                        if which == 0:
                            best_plain = max(best_plain, r)
                        else:
                            best_lifted = max(best_lifted, r)
        print(f"| {width} | {best_plain:.2f} | {best_lifted:.2f} |")


if __name__ == "__main__":
    main()
