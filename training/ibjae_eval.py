"""IBJAE's evaluation as the paper's Table IV: retrieval of the test
queries' bend from the nominal silhouette database, by the SCNN's
embedding and, beside it, by the raw-pixel Hamming distance.

A query is a segmented frame of the simulated robot (x^b of D^I) with its
true pose; it is looked up among the database entries of its own band (the
band of its true pose: IBJAE reads the band of the robot's translation and
current bend), and its estimate is the nearest entry's θ. Figures: RMSE of
that estimate against the true θ over every test query (the full range)
and over those with θ in [0°, 50°] (the paper's range; the database is
still the band's), the share within 1°, and the same for the Hamming
nearest neighbour on the same queries and database.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import torch

PAPER_RANGE_DEG = (0.0, 50.0)


def embed(model: torch.nn.Module, masks: np.ndarray, device: torch.device, batch: int = 512) -> np.ndarray:
    """Embeddings ``[n, 256]`` of bool masks ``[n, 48, 48]`` (eval mode)."""
    model.eval()
    out = []
    with torch.no_grad():
        for start in range(0, len(masks), batch):
            x = torch.from_numpy(masks[start : start + batch].astype(np.float32)[:, None]).to(device)
            out.append(model(x).cpu().numpy())
    return np.concatenate(out) if out else np.zeros((0, 256), np.float32)


def nearest_l2(queries: np.ndarray, entries: np.ndarray) -> np.ndarray:
    """Index of each query's nearest entry by Euclidean distance."""
    d = (queries**2).sum(1)[:, None] + (entries**2).sum(1)[None, :] - 2.0 * queries @ entries.T
    return np.argmin(d, axis=1)


def nearest_hamming(queries: np.ndarray, entries: np.ndarray) -> np.ndarray:
    """Index of each query's nearest entry by Hamming distance on flattened bool masks."""
    q = queries.reshape(len(queries), -1).astype(np.float32)
    e = entries.reshape(len(entries), -1).astype(np.float32)
    d = q.sum(1)[:, None] + e.sum(1)[None, :] - 2.0 * q @ e.T
    return np.argmin(d, axis=1)


def retrieve(
    query_band: np.ndarray,
    db_band: np.ndarray,
    db_theta: np.ndarray,
    nearest: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> np.ndarray:
    """θ estimate of each query: ``nearest(query_rows, entry_rows)`` within
    each band; ``nearest`` takes the queries' and the band's indices."""
    out = np.full(len(query_band), np.nan)
    for band in np.unique(query_band):
        rows = np.flatnonzero(query_band == band)
        entries = np.flatnonzero(db_band == band)
        if len(entries):
            out[rows] = db_theta[entries[nearest(rows, entries)]]
    return out


def scores(estimate: np.ndarray, theta: np.ndarray) -> dict[str, float]:
    """RMSE (full range, paper range) and share within 1°."""
    err = estimate - theta
    lo, hi = PAPER_RANGE_DEG
    paper = (theta >= lo) & (theta <= hi)

    def rmse(e: np.ndarray) -> float:
        return float(np.sqrt(np.mean(e**2))) if len(e) else float("nan")

    return {
        "rmse_deg": rmse(err),
        "rmse_paper_range_deg": rmse(err[paper]),
        "within_1deg": float(np.mean(np.abs(err) <= 1.0)) if len(err) else float("nan"),
        "queries": len(err),
        "queries_paper_range": int(paper.sum()),
    }


def evaluate(
    model: torch.nn.Module,
    device: torch.device,
    db: dict[str, np.ndarray],
    queries: dict[str, np.ndarray],
) -> dict[str, Any]:
    """Table IV on ``queries`` (``x_b``, ``theta_deg``, ``band``) against ``db``
    (``masks``, ``theta_deg``, ``band``): the SCNN's retrieval and the
    Hamming baseline's."""
    db_emb = embed(model, db["masks"], device)
    q_emb = embed(model, queries["x_b"], device)
    scnn = retrieve(queries["band"], db["band"], db["theta_deg"], lambda r, e: nearest_l2(q_emb[r], db_emb[e]))
    hamming = retrieve(
        queries["band"],
        db["band"],
        db["theta_deg"],
        lambda r, e: nearest_hamming(queries["x_b"][r], db["masks"][e]),
    )
    out = {"scnn": scores(scnn, queries["theta_deg"]), "hamming": scores(hamming, queries["theta_deg"])}
    s, h = out["scnn"]["rmse_paper_range_deg"], out["hamming"]["rmse_paper_range_deg"]
    out["hamming_over_scnn_rmse_paper_range"] = float(h / s) if s > 0 else float("nan")
    s, h = out["scnn"]["rmse_deg"], out["hamming"]["rmse_deg"]
    out["hamming_over_scnn_rmse"] = float(h / s) if s > 0 else float("nan")
    return out
