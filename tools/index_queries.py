#!/usr/bin/env python3
"""Real queries for the feature index benchmark: a trained database's bands
and the SCNN embeddings of fresh frames of the simulated robot, per band.

`tools/index_bench.py --database DIR --scnn FILE` runs this first (in the
project's `.venv`, where `kflex` is installed; `make venv` makes it), then
times the index on what it writes. For each band of the database
(`band-000.kfdb`, … as `kflex-cli build-db` writes them) that holds at
least one query, it writes `OUT/band-NNN/` with

  * `db.npy`: the band's features (N×256 float32), `poses.npy`: their
    (θ deg, d mm) (N×2 float64), as the database file holds them;
  * `queries.npy`: the embeddings (Q×256 float32) of the segmented 48×48
    silhouettes of as-built frames whose true pose lies in the band, made
    as the training set's x^b are (`kflex.ImagePairsConfig`: as-built
    instrument and camera, backgrounds, gain, noise and blur drawn per
    frame, the shipped segmentation), one row a frame.

That is what IBJAE asks of each band's index in the loop: one query at a
time among that band's entries. Prints one JSON line: the bands written,
their sizes and query counts.

Usage: .venv/bin/python tools/index_queries.py --database DIR --scnn FILE --out DIR
       [--frames 2000] [--seed 7]
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import kflex


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--database", type=Path, required=True, help="directory of band-NNN.kfdb files")
    ap.add_argument("--scnn", type=Path, required=True, help="the SCNN (ONNX) the database was built with")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--frames", type=int, default=2000, help="frames to make (about one query each)")
    ap.add_argument("--seed", type=int, default=7, help="seed of the frames (not the training set's 2020)")
    args = ap.parse_args()

    files = sorted(args.database.glob("band-*.kfdb"))
    if not files:
        print(f"error: no band-NNN.kfdb files in {args.database}", file=sys.stderr)
        return 2
    scnn = kflex.Scnn.load(args.scnn)
    config = kflex.ImagePairsConfig()
    config.pairs = 2 * args.frames  # two pairs a frame (a positive and a negative)
    config.seed = args.seed
    arrays, _card = config.generate()
    # one row a frame: a frame's pairs share its x^b
    first = np.unique(arrays["query"], return_index=True)[1]
    masks = arrays["x_b"][first]
    bands = arrays["band"][first].astype(int)
    embeddings = scnn.embed(masks)

    written = []
    for path in files:
        band = int(path.stem.split("-")[1])
        rows = np.flatnonzero(bands == band)
        if len(rows) == 0:
            continue
        index = kflex.FeatureIndex.load(path)
        if index.metadata.get("scnn_sha256") not in (None, scnn.sha256):
            print(f"error: {path} was built with another SCNN than {args.scnn}", file=sys.stderr)
            return 2
        out = args.out / path.stem
        out.mkdir(parents=True, exist_ok=True)
        np.save(out / "db.npy", np.ascontiguousarray(index.features, dtype=np.float32))
        poses = np.stack([index.theta_deg, index.translation_mm], axis=1).astype(np.float64)
        np.save(out / "poses.npy", poses)
        np.save(out / "queries.npy", np.ascontiguousarray(embeddings[rows], dtype=np.float32))
        written.append({"band": band, "dir": str(out), "n": len(index), "queries": len(rows)})
    print(json.dumps({"bands": written, "frames": len(first)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
