#!/usr/bin/env python3
"""Golden reference values for kflex's PaperKalman, from filterpy's KalmanFilter.

The paper's LBHJAE filter: state [theta, theta'], F = [[1, dt], [0, 1]],
Q = G G^T sigma_a^2 with G = [dt^2/2, dt]^T, H = [1, 0] for both sensors,
R = sigma_z^2 per sensor, x0 = 0, P0 = 0. Each filter step predicts, then
updates with KBJAE (sensor 1), then IBJAE (sensor 2); a missing measurement
(an empty field in the CSV) is skipped, as filterpy's update(None) does.

Each case is a sequence of ticks of the loop: columns
    tick, z1, z2, theta, rate, p00, p01, p11
the state after the tick. "As run" cases step the filter every tick; the
"as written" case steps it once every `every` ticks (with that tick's
measurements) and holds the state in between.

Usage:
    python tools/golden/kalman_golden.py            # write the CSVs
    python tools/golden/kalman_golden.py --check    # recompute and compare
    python tools/golden/kalman_golden.py --out DIR  # other folder

Requires numpy and filterpy 2.0.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from filterpy.kalman import KalmanFilter

DEFAULT_OUT = Path(__file__).resolve().parent.parent.parent / "crates" / "kflex-estimate" / "tests" / "data"
CHECK_RTOL = 1e-12
CHECK_ATOL = 1e-12
COLUMNS = ["tick", "z1", "z2", "theta", "rate", "p00", "p01", "p11"]


@dataclass(frozen=True)
class Case:
    name: str
    model_dt: float
    sigma_a: float
    sigma_z: tuple[float, float]
    ticks: int
    tick_s: float
    every: int  # filter steps every `every` ticks (1: as run)
    seed: int


def cases() -> list[Case]:
    return [
        Case("paper_as_run", 0.1, 0.01, (0.01, 0.01), 700, 0.01, 1, 1),
        Case("loose_as_run", 0.05, 2.0, (1.5, 3.0), 500, 0.02, 1, 2),
        Case("paper_as_written", 0.1, 0.01, (0.01, 0.01), 700, 0.01, 10, 3),
    ]


def measurements(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """The paper's input as the truth; KBJAE with a lag-like error and noise,
    IBJAE with noise; each missing now and then (NaN)."""
    rng = np.random.default_rng(case.seed)
    t = np.arange(1, case.ticks + 1) * case.tick_s
    truth = 25.0 * np.sin(t) + 25.0
    z1 = truth - 3.0 * np.cos(t) + rng.normal(0.0, 1.0, t.size)
    z2 = truth + rng.normal(0.0, 2.5, t.size)
    z1[rng.random(t.size) < 0.05] = np.nan
    z2[rng.random(t.size) < 0.3] = np.nan
    return z1, z2


def run(case: Case) -> np.ndarray:
    z1, z2 = measurements(case)
    kf = KalmanFilter(dim_x=2, dim_z=1)
    dt = case.model_dt
    kf.x = np.zeros((2, 1))
    kf.P = np.zeros((2, 2))
    kf.F = np.array([[1.0, dt], [0.0, 1.0]])
    g = np.array([[0.5 * dt * dt], [dt]])
    kf.Q = g @ g.T * case.sigma_a**2
    kf.H = np.array([[1.0, 0.0]])
    rows = []
    for i in range(case.ticks):
        if (i + 1) % case.every == 0:
            kf.predict()
            for z, s in ((z1[i], case.sigma_z[0]), (z2[i], case.sigma_z[1])):
                kf.update(None if math.isnan(z) else z, R=s * s)
        x, p = kf.x[:, 0], kf.P
        rows.append([i, z1[i], z2[i], x[0], x[1], p[0, 0], p[0, 1], p[1, 1]])
    return np.array(rows)


def csv_path(out: Path, case: Case) -> Path:
    return out / f"kalman_{case.name}.csv"


def write_case(path: Path, data: np.ndarray) -> None:
    lines = [",".join(COLUMNS)]
    for row in data:
        cells = [str(int(row[0]))]
        cells += ["" if math.isnan(v) else repr(float(v)) for v in row[1:]]
        lines.append(",".join(cells))
    tmp = path.with_suffix(".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(path)


def read_case(path: Path) -> np.ndarray:
    rows = []
    for line in path.read_text().splitlines()[1:]:
        rows.append([float(c) if c else math.nan for c in line.split(",")])
    return np.array(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    bad = 0
    for case in cases():
        data = run(case)
        path = csv_path(args.out, case)
        if args.check:
            stored = read_case(path)
            same = stored.shape == data.shape and np.allclose(
                stored, data, rtol=CHECK_RTOL, atol=CHECK_ATOL, equal_nan=True)
            print(f"{case.name}: {'ok' if same else 'DIFFERS'}")
            bad += not same
        else:
            write_case(path, data)
            print(f"wrote {path}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
