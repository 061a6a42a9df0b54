"""Golden reference values for the Bouc-Wen hysteresis operator.

Model (rate-independent form), input x(t), hysteretic state z(t), z(0) = 0:

    dz/dt = A*xdot - beta*|xdot|*sign(z)*|z|^n - gamma*xdot*|z|^n

Each case drives the model with x(t) = X*sin(2*pi*f*t) + X0 and integrates the
ODE in time with scipy's DOP853 (rtol=1e-11, atol=1e-13) using the analytic
xdot. The sample spacing is 1/(4*f*m), so the sine's turning points fall
exactly on sample times. The integration is split at those turning points:
|xdot| has a kink there, and within one segment sign(xdot) is a constant.

Usage:
    python tools/golden/bouc_wen_golden.py            # write the CSVs
    python tools/golden/bouc_wen_golden.py --check    # recompute and compare
    python tools/golden/bouc_wen_golden.py --out DIR  # other folder

Requires Python 3.11, numpy and scipy only.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

SCRIPT_REL = "tools/golden/bouc_wen_golden.py"
DEFAULT_OUT = (
    Path(__file__).resolve().parent.parent.parent
    / "crates"
    / "kflex-model"
    / "tests"
    / "data"
)
PARAM_NAMES = ("A", "beta", "gamma", "n")
RTOL = 1e-11
ATOL = 1e-13
# Recomputing on another CPU reproduces the stored values only to the
# integrator's global error, not bit for bit: numpy's SIMD maths differ in
# the last ulp between CPUs, so DOP853 chooses other steps. Seen: 2.2e-10
# absolute on z ~ 0.02 (an AMD EPYC against the machine that wrote the
# files). The absolute floor sits above that and far below any edit that
# would matter to the Rust tests, which compare against the stored files.
CHECK_RTOL = 1e-9
CHECK_ATOL = 1e-9


@dataclass(frozen=True)
class Case:
    name: str
    A: float
    beta: float
    gamma: float
    n: float
    X: float  # amplitude
    X0: float  # offset
    f: float  # frequency [Hz]
    T: float  # end time (inclusive)
    m: int  # samples per quarter period

    @property
    def dt(self) -> float:
        return 1.0 / (4.0 * self.f * self.m)

    @property
    def num_intervals(self) -> int:
        """N: the case has N+1 samples, t_i = i*dt for i = 0..N."""
        n_float = self.T / self.dt
        n_int = round(n_float)
        if abs(n_float - n_int) > 1e-9 * max(1.0, n_float):
            raise ValueError(
                f"{self.name}: T={self.T} is not a multiple of dt={self.dt}"
            )
        return n_int

    @property
    def z_bound(self) -> float:
        """Saturation level (A/(beta+gamma))**(1/n); |z| stays below it from z(0)=0."""
        return (self.A / (self.beta + self.gamma)) ** (1.0 / self.n)

    def params(self) -> dict[str, float]:
        return {"A": self.A, "beta": self.beta, "gamma": self.gamma, "n": self.n}


def cases() -> list[Case]:
    """The golden cases, in file order."""
    return [
        Case(
            "n1_sym",
            A=1.0,
            beta=0.5,
            gamma=0.5,
            n=1.0,
            X=3.0,
            X0=0.0,
            f=1.0,
            T=3.0,
            m=100,
        ),
        Case(
            "n2", A=1.0, beta=0.7, gamma=0.3, n=2.0, X=2.0, X0=0.5, f=0.5, T=6.0, m=100
        ),
        Case(
            "n1p5_soft",
            A=2.0,
            beta=1.2,
            gamma=-0.4,
            n=1.5,
            X=4.0,
            X0=0.0,
            f=2.0,
            T=1.5,
            m=100,
        ),
        # Small amplitude: the loop never gets near saturation.
        Case(
            "n1_small",
            A=1.0,
            beta=2.0,
            gamma=1.0,
            n=1.0,
            X=0.2,
            X0=0.0,
            f=1.0,
            T=3.0,
            m=100,
        ),
    ]


def case_by_name(name: str) -> Case:
    for c in cases():
        if c.name == name:
            return c
    raise KeyError(name)


def sample_times(case: Case) -> np.ndarray:
    n_int = case.num_intervals
    # i / (4 f m) rather than i * dt: turning points (i = multiple of m) come out exact.
    return np.arange(n_int + 1, dtype=float) / (4.0 * case.f * case.m)


def compute_case(case: Case) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate one case; returns (t, x, z) at the sample times."""
    t = sample_times(case)
    w = 2.0 * math.pi * case.f
    x = case.X * np.sin(w * t) + case.X0

    def xdot(tt: float) -> float:
        return case.X * w * math.cos(w * tt)

    A, beta, gamma, n = case.A, case.beta, case.gamma, case.n
    z = np.empty_like(t)
    z[0] = 0.0
    m = case.m
    n_int = case.num_intervals
    # Segments between turning points: samples [k*m, (k+1)*m] (the last may be short).
    starts = list(range(0, n_int, m))
    for i0 in starts:
        i1 = min(i0 + m, n_int)
        t_seg = t[i0 : i1 + 1]
        # Sign of xdot inside the segment (constant there; zero only at the ends).
        s = math.copysign(1.0, xdot(0.5 * (t_seg[0] + t_seg[-1])))

        def rhs(tt: float, y: np.ndarray, s: float = s) -> np.ndarray:
            zz = y[0]
            v = xdot(tt)
            az_n = abs(zz) ** n
            return np.array(
                [A * v - beta * (s * v) * math.copysign(az_n, zz) - gamma * v * az_n]
            )

        sol = solve_ivp(
            rhs,
            (t_seg[0], t_seg[-1]),
            [z[i0]],
            method="DOP853",
            t_eval=t_seg,
            rtol=RTOL,
            atol=ATOL,
            max_step=case.dt,
        )
        if not sol.success:
            raise RuntimeError(f"{case.name}: solve_ivp failed: {sol.message}")
        z[i0 + 1 : i1 + 1] = sol.y[0, 1:]

    bound = case.z_bound + 1e-9
    zmax = float(np.max(np.abs(z)))
    assert zmax <= bound, f"{case.name}: max|z|={zmax!r} exceeds bound {bound!r}"
    return t, x, z


def csv_path(out_dir: Path, case: Case) -> Path:
    return out_dir / f"bouc_wen_{case.name}.csv"


def header_comment(case: Case) -> str:
    params = ",".join(f"{k}={v!r}" for k, v in case.params().items())
    return f"# {params} generated by {SCRIPT_REL}"


def write_case(
    path: Path, case: Case, t: np.ndarray, x: np.ndarray, z: np.ndarray
) -> None:
    lines = [header_comment(case), "t,x,z"]
    lines += [f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, x, z, strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="ascii")


def parse_header(path: Path) -> dict[str, float]:
    """Parameters from a stored file's first comment line."""
    with path.open(encoding="ascii") as fh:
        first = fh.readline().strip()
    if not first.startswith("# "):
        raise ValueError(f"{path}: first line is not a '# ' comment: {first!r}")
    params_part = first[2:].split(" ", 1)[0]
    params: dict[str, float] = {}
    for item in params_part.split(","):
        key, _, val = item.partition("=")
        params[key] = float(val)
    return params


def read_case(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, x, z) columns of a stored file."""
    with path.open(encoding="ascii") as fh:
        fh.readline()  # comment
        header = fh.readline().strip()
        if header != "t,x,z":
            raise ValueError(f"{path}: expected header 't,x,z', got {header!r}")
        data = np.loadtxt(fh, delimiter=",", ndmin=2)
    return data[:, 0], data[:, 1], data[:, 2]


def check_case(path: Path, case: Case) -> list[str]:
    """Problems found comparing a stored file with a fresh computation (empty = OK)."""
    if not path.is_file():
        return [f"{path}: missing"]
    problems = []
    stored_params = parse_header(path)
    if stored_params != case.params():
        problems.append(
            f"{path}: header params {stored_params} != case {case.params()}"
        )
    ts, xs, zs = read_case(path)
    t, x, z = compute_case(case)
    if ts.shape != t.shape:
        return [*problems, f"{path}: {ts.shape[0]} rows, expected {t.shape[0]}"]
    for label, got, want in (("t", ts, t), ("x", xs, x), ("z", zs, z)):
        if not np.allclose(got, want, rtol=CHECK_RTOL, atol=CHECK_ATOL):
            err = np.abs(got - want)
            i = int(np.argmax(err - CHECK_RTOL * np.abs(want)))
            problems.append(
                f"{path}: column {label} differs (max abs err {err.max():.3e}; "
                f"row {i}: stored {float(got[i])!r}, recomputed {float(want[i])!r})"
            )
    return problems


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument(
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        help=f"data folder (default {DEFAULT_OUT})",
    )
    ap.add_argument(
        "--check",
        action="store_true",
        help=f"recompute, compare with --out (rtol {CHECK_RTOL}, atol {CHECK_ATOL})",
    )
    args = ap.parse_args(argv)
    out: Path = args.out

    if args.check:
        problems: list[str] = []
        for case in cases():
            problems += check_case(csv_path(out, case), case)
        if problems:
            print("bouc_wen_golden --check: MISMATCH", file=sys.stderr)
            for p in problems:
                print("  " + p, file=sys.stderr)
            return 1
        print(f"bouc_wen_golden --check: all {len(cases())} cases match in {out}")
        return 0

    out.mkdir(parents=True, exist_ok=True)
    for case in cases():
        t, x, z = compute_case(case)
        path = csv_path(out, case)
        write_case(path, case, t, x, z)
        print(
            f"{path}: {t.size} rows, max|z|={np.max(np.abs(z)):.15g} "
            f"(bound {case.z_bound:.15g})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
