#!/usr/bin/env python3
"""Times PyBullet's TinyRenderer side by side with kflex's renderer, one core.

Both draw the same instrument: the K-FLEX capsule chain that
`cargo run --release -p kflex-model --example export_shapes` writes (bodies in
the camera frame, a sweep of poses), the pose changing every call. kflex's
rates come from the `render_rates` example; TinyRenderer's from
`pybullet.getCameraImage(..., renderer=ER_TINY_RENDERER)` in DIRECT mode, each
body created once as a visual shape (GEOM_CAPSULE for round ends,
GEOM_CYLINDER for flat) and moved per pose with resetBasePositionAndOrientation
(the moves are inside the timed loop, as the shape's preparation is in
kflex's).

The comparison is of cost, not of pixels: kflex's default camera has a
wide-angle lens (barrel distortion), a textured background and sensor noise;
TinyRenderer is a pinhole over a flat background, given the same intrinsics.

Usage: python3 tools/tinyrenderer_compare.py [--rounds N] [--seconds S] [--out DIR]

The first run makes tools/.venv-pybullet/ and installs pybullet and numpy
from PyPI into it (pybullet may compile from source for a few minutes), then
re-executes itself there. It saves TinyRenderer's 640x480 frame at θ = 30°,
d = 10 mm and kflex-cli's to DIR (default out/tinyrenderer) for a person to
compare.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "tools" / ".venv-pybullet"
VPY = VENV / "bin" / "python"
ONE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RAYON_NUM_THREADS")}
NEAR_MM, FAR_MM = 0.1, 1000.0
# what -> (words, kflex's goal)
ROWS = {
    "silhouette_48": ("48x48 silhouette of the working region", ">= 30,000/s"),
    "frame_640x480": ("640x480 shaded frame", ">= 300/s"),
    "roi_window": ("working region alone, full resolution", ">= 1,500/s"),
}


def ensure_venv() -> None:
    """Re-executes this script inside tools/.venv-pybullet, making it first if missing."""
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    if not VPY.exists():
        print(f"making {VENV.relative_to(ROOT)} and installing pybullet and numpy from PyPI "
              "(pybullet may compile for a few minutes) ...", flush=True)
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
        subprocess.run([str(VPY), "-m", "pip", "install", "--quiet", "--upgrade", "pip"], check=True)
        subprocess.run([str(VPY), "-m", "pip", "install", "--quiet", "pybullet", "numpy"], check=True)
    os.execve(str(VPY), [str(VPY), str(Path(__file__).resolve()), *sys.argv[1:]], {**os.environ, **ONE_THREAD})


def target_dir() -> Path:
    return Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")).resolve()


def build() -> None:
    print("building kflex (release) ...", flush=True)
    cmd = ["cargo", "build", "--release", "--quiet", "-p", "kflex-model",
           "--example", "export_shapes", "--example", "render_rates", "-p", "kflex-cli", "--bin", "kflex-cli"]
    subprocess.run(cmd, cwd=ROOT, check=True)


def pinned(cmd: list[str]) -> list[str]:
    return (["taskset", "-c", "0"] + cmd) if shutil.which("taskset") else cmd


def export(*args: str) -> dict:
    exe = target_dir() / "release" / "examples" / "export_shapes"
    out = subprocess.run([str(exe), *args], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def kflex_rates(seconds: float) -> dict[str, float]:
    exe = target_dir() / "release" / "examples" / "render_rates"
    out = subprocess.run(pinned([str(exe), str(seconds)]), check=True, capture_output=True, text=True,
                         env={**os.environ, **ONE_THREAD}).stdout
    rates = {}
    for line in out.splitlines():
        who, what, per_s = line.split()
        if who == "kflex":
            rates[what] = float(per_s)
    return rates


def projection(fx: float, fy: float, cx: float, cy: float, w: int, h: int) -> list[float]:
    """OpenGL projection (column-major) of a pinhole with these intrinsics.

    The view matrix turns kflex's camera frame (x right, y down, z forward)
    into OpenGL's (y up, looking along -z); pixel (u, v) with v down then maps
    to NDC x = 2u/w - 1, y = 1 - 2v/h. Pixel centres are at half-integers in
    kflex, as in OpenGL, so cx, cy carry over unchanged.
    """
    a = -(FAR_MM + NEAR_MM) / (FAR_MM - NEAR_MM)
    b = -2.0 * FAR_MM * NEAR_MM / (FAR_MM - NEAR_MM)
    return [2 * fx / w, 0, 0, 0,
            0, 2 * fy / h, 0, 0,
            1 - 2 * cx / w, 2 * cy / h - 1, a, -1,
            0, 0, b, 0]


# kflex's camera frame to OpenGL's eye frame: flip y and z (column-major).
VIEW = [1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1]


def body_pose(a: list[float], b: list[float]) -> tuple[list[float], list[float], float]:
    """Centre, quaternion (x, y, z, w) turning +z onto a->b, and the axis length."""
    d = [b[i] - a[i] for i in range(3)]
    length = math.sqrt(sum(x * x for x in d))
    centre = [(a[i] + b[i]) / 2 for i in range(3)]
    if length < 1e-12:
        return centre, [0.0, 0.0, 0.0, 1.0], 0.0
    u = [x / length for x in d]
    # half-way quaternion: rotation from z = (0, 0, 1) to u
    w = 1.0 + u[2]
    if w < 1e-9:  # u = -z: half a turn about x
        return centre, [1.0, 0.0, 0.0, 0.0], length
    q = [-u[1], u[0], 0.0, w]
    n = math.sqrt(sum(x * x for x in q))
    return centre, [x / n for x in q], length


class Tiny:
    """The capsule chain in a PyBullet DIRECT session, bodies made once."""

    def __init__(self, poses: list[dict]):
        import pybullet as p

        self.p = p
        self.client = p.connect(p.DIRECT)
        first = poses[0]["bodies"]
        if any(len(q["bodies"]) != len(first) for q in poses):
            raise SystemExit("the poses differ in their number of bodies")
        self.ids = []
        for i, body in enumerate(first):
            _, _, length = body_pose(body["a_mm"], body["b_mm"])
            lengths = [body_pose(q["bodies"][i]["a_mm"], q["bodies"][i]["b_mm"])[2] for q in poses]
            if max(lengths) - min(lengths) > 1e-3:
                print(f"note: body {i}'s length varies over the poses ({min(lengths):.3f}-{max(lengths):.3f} mm); "
                      "TinyRenderer keeps the first", flush=True)
            shape = p.GEOM_CAPSULE if body["round"] else p.GEOM_CYLINDER
            vis = p.createVisualShape(shape, radius=body["radius_mm"], length=length,
                                      rgbaColor=[0.75, 0.75, 0.78, 1.0], physicsClientId=self.client)
            self.ids.append(p.createMultiBody(baseMass=0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=vis,
                                              physicsClientId=self.client))
        # per pose, per body: centre and orientation, worked out before any timing
        self.poses = [[body_pose(b["a_mm"], b["b_mm"])[:2] for b in q["bodies"]] for q in poses]

    def place(self, k: int) -> None:
        for body, (centre, quat) in zip(self.ids, self.poses[k]):
            self.p.resetBasePositionAndOrientation(body, centre, quat, physicsClientId=self.client)

    def image(self, k: int, intr: dict, w: int, h: int, flags: int):
        self.place(k)
        proj = projection(intr["fx"], intr["fy"], intr["cx"], intr["cy"], w, h)
        return self.p.getCameraImage(w, h, VIEW, proj, shadow=0, flags=flags,
                                     renderer=self.p.ER_TINY_RENDERER, physicsClientId=self.client)

    def rate(self, seconds: float, intr: dict, w: int, h: int, flags: int) -> float:
        n, calls = len(self.poses), 0
        start = time.perf_counter()
        while True:
            self.image(calls % n, intr, w, h, flags)
            calls += 1
            elapsed = time.perf_counter() - start
            if elapsed >= seconds:
                return calls / elapsed


def tiny_rates(tiny: Tiny, geo: dict, seconds: float) -> dict[str, float]:
    p = tiny.p
    roi, full = geo["roi"], geo["intrinsics"]
    roi_full = {**full, "cx": full["cx"] - roi["x0"], "cy": full["cy"] - roi["y0"]}
    return {
        # TinyRenderer always draws colour and depth too; the segmentation mask is what is asked for
        "silhouette_48": tiny.rate(seconds, geo["roi_intrinsics_48"], 48, 48, 0),
        "frame_640x480": tiny.rate(seconds, full, full["width"], full["height"], p.ER_NO_SEGMENTATION_MASK),
        "roi_window": tiny.rate(seconds, roi_full, roi["width"], roi["height"], p.ER_NO_SEGMENTATION_MASK),
    }


def write_png(path: Path, rgb: bytes, w: int, h: int) -> None:
    """An 8-bit RGB PNG, no dependency beyond zlib."""
    raw = b"".join(b"\x00" + rgb[y * w * 3:(y + 1) * w * 3] for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def save_check(out: Path) -> None:
    """TinyRenderer's and kflex-cli's 640x480 frames at θ = 30°, d = 10 mm, for a person to compare."""
    import numpy as np

    out.mkdir(parents=True, exist_ok=True)
    geo = export("--pose", "30", "10")
    tiny = Tiny(geo["poses"])
    k = geo["intrinsics"]
    _, _, rgba, _, seg = tiny.image(0, k, k["width"], k["height"], 0)
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(k["height"], k["width"], 4)[:, :, :3].copy()
    # the working region's outline, to place the two against each other
    r = geo["roi"]
    x0, y0, x1, y1 = r["x0"], r["y0"], r["x0"] + r["width"] - 1, r["y0"] + r["height"] - 1
    rgb[y0, x0:x1 + 1] = rgb[y1, x0:x1 + 1] = rgb[y0:y1 + 1, x0] = rgb[y0:y1 + 1, x1] = (255, 0, 0)
    write_png(out / "tinyrenderer_640x480.png", rgb.tobytes(), k["width"], k["height"])
    p = tiny.p
    p.disconnect(tiny.client)
    cli = target_dir() / "release" / "kflex-cli"
    subprocess.run([str(cli), "render", "--theta", "30", "--d", "10", "--out", str(out / "kflex")], check=True,
                   capture_output=True)
    seg = np.asarray(seg).reshape(k["height"], k["width"])
    print(f"check frames (θ 30°, d 10 mm) in {out}: tinyrenderer_640x480.png (working region outlined), "
          f"kflex/frame.png; TinyRenderer's instrument covers {int((seg >= 0).sum())} px", flush=True)


def fmt(x: float) -> str:
    return f"{x:,.0f}" if x >= 100 else f"{x:,.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=6, help="alternations of kflex and TinyRenderer")
    ap.add_argument("--seconds", type=float, default=2.0, help="seconds per rate per round")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "tinyrenderer", help="where the check frames go")
    args = ap.parse_args()
    ensure_venv()
    build()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {0})
    import pybullet as p

    save_check(args.out)
    geo = export()
    print(f"{len(geo['poses'])} poses, {len(geo['poses'][0]['bodies'])} bodies each; "
          f"working region {geo['roi']['width']}x{geo['roi']['height']} px; "
          f"pybullet {p.getAPIVersion()}, numpy {'on' if p.isNumpyEnabled() else 'off'}", flush=True)
    tiny = Tiny(geo["poses"])
    runs: dict[str, list[tuple[float, float]]] = {what: [] for what in ROWS}
    for i in range(args.rounds):
        kf = kflex_rates(args.seconds)
        tr = tiny_rates(tiny, geo, args.seconds)
        for what in ROWS:
            runs[what].append((kf[what], tr[what]))
        print(f"round {i + 1}/{args.rounds}: " + ", ".join(
            f"{what} {fmt(kf[what])} vs {fmt(tr[what])}/s" for what in ROWS), flush=True)
    print()
    print("| what (one core) | kflex /s, median (range) | TinyRenderer /s, median (range) "
          "| kflex / TinyRenderer, median (range) | kflex's goal |")
    print("|---|---|---|---|---|")
    for what, (words, goal) in ROWS.items():
        kf = [a for a, _ in runs[what]]
        tr = [b for _, b in runs[what]]
        ratio = [a / b for a, b in runs[what]]
        print(f"| {words} | {fmt(statistics.median(kf))} ({fmt(min(kf))}-{fmt(max(kf))}) "
              f"| {fmt(statistics.median(tr))} ({fmt(min(tr))}-{fmt(max(tr))}) "
              f"| {statistics.median(ratio):.1f}x ({min(ratio):.1f}-{max(ratio):.1f}) | {goal} |")


if __name__ == "__main__":
    main()
