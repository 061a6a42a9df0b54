#!/usr/bin/env python3
"""Prints the benchmark figures against the goals the issues set.

Reads criterion's estimates under target/criterion (run `make bench` first) and
prints one row per benchmark: median and mean time per iteration, the rate it
gives, the goal, and whether the median meets it. Exit status 1 if a goal is
missed, 2 if a benchmark has no estimates yet.
"""

import json
import sys
from pathlib import Path

# benchmark -> (what one iteration is, goal on the median in seconds, the goal in words)
GOALS = {
    "analytic_tick": ("plant tick (analytic joint, 20-element sheath)", 1 / 200_000, ">= 200,000/s"),
    "rapier_tick": ("plant tick (rapier3d joint)", None, ""),
    "silhouette_48x48": ("48x48 silhouette", 1 / 30_000, ">= 30,000/s"),
    "silhouette_640x480": ("640x480 silhouette", None, ""),
    "shaded_640x480": ("shaded 640x480 frame, every realism feature", 1 / 300, ">= 300/s"),
    "shaded_roi": ("shaded working region alone (render_window)", 1 / 1_500, ">= 1,500/s"),
    "segment_working_roi": ("segmentation, working region, kept Segmenter", 2e-4, "<= 0.2 ms median"),
    "segment_640x480": ("segmentation, 640x480, kept Segmenter", 1e-3, "<= 1 ms median"),
    "segment_1920x1080": ("segmentation, 1920x1080, kept Segmenter", 5e-3, "<= 5 ms median"),
    "segment_640x480_one_off": ("segmentation, 640x480, one-off", None, ""),
    "segment_1920x1080_one_off": ("segmentation, 1920x1080, one-off", None, ""),
    # the feature index (kflex-estimate feature `index`), batch 1, 256-d; the
    # ratio goals (>= 10x a linear scan, faster than cKDTree and faiss) are
    # checked by tools/index_bench.py on the same data
    **{
        f"index_query/{kind}/{n}": (f"feature index, {label}, N = {n:,}", None, "")
        for n in (1_000, 6_000, 10_000, 100_000)
        for kind, label in (("exact_index", "exact index"), ("linear_scan", "linear scan"))
    },
}


def fmt_time(s: float) -> str:
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9)):
        if s >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s:.3g} s"


def main() -> int:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "target/criterion")
    rows, status = [], 0
    for name, (what, goal, words) in GOALS.items():
        path = root / name / "new" / "estimates.json"
        if not path.is_file():
            rows.append((what, "-", "-", "-", words, "not run"))
            status = max(status, 2)
            continue
        est = json.loads(path.read_text())
        median = est["median"]["point_estimate"] * 1e-9
        mean = est["mean"]["point_estimate"] * 1e-9
        verdict = ""
        if goal is not None:
            ok = median <= goal
            verdict = "meets" if ok else "MISSES"
            status = max(status, 0 if ok else 1)
        rows.append((what, fmt_time(median), fmt_time(mean), f"{1 / median:,.0f}/s", words, verdict))
    head = ("benchmark", "median", "mean", "rate", "goal", "")
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    for r in [head] + rows:
        print("  ".join(str(c).ljust(w) for c, w in zip(r, widths)).rstrip())
    return status


if __name__ == "__main__":
    sys.exit(main())
