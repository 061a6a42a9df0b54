"""Data sets on disk: numpy's ``.npz`` with a JSON card beside each file.

``save(path, arrays, card)`` writes ``NAME.npz`` and ``NAME.card.json``
(the generator's card plus the file's name, size and SHA-256), each
atomically: written to a temporary file in the same folder, flushed to
disk, then renamed over the target, so a reader never sees half a file and
an interrupted write leaves the old one in place. ``load(path)`` reads both
back and checks the SHA-256.

>>> import kflex, kflex.npz
>>> arrays, card = kflex.KinematicDatasetConfig(samples_per_set=100).generate()
>>> path = kflex.npz.save("data/kinematic.npz", arrays, card)  # doctest: +SKIP
>>> arrays, card = kflex.npz.load(path)  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

__all__ = ["card_path", "load", "save", "sha256", "write_atomically"]


def card_path(path: str | os.PathLike[str]) -> Path:
    """The card beside a data file: ``NAME.card.json`` for ``NAME.npz``."""
    p = Path(path)
    return p.with_name(p.stem + ".card.json")


def write_atomically(target: Path, write: Callable[[IO[bytes]], None]) -> None:
    """Calls ``write`` on a temporary file in ``target``'s folder, flushes it
    to disk, then renames it over ``target`` (made with its folders)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp's 0600 is for the temporary file only
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def sha256(path: Path) -> str:
    """The file's SHA-256, hex."""
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def save(
    path: str | os.PathLike[str],
    arrays: Mapping[str, np.ndarray],
    card: Mapping[str, Any],
    *,
    compress: bool = True,
) -> Path:
    """Writes ``arrays`` to ``path`` (``.npz``, compressed unless
    ``compress=False``) and ``card`` with ``file``, ``bytes`` and ``sha256``
    added to ``NAME.card.json`` beside it; both atomically. Returns the path.

    Raises ``ValueError`` for a path that does not end in ``.npz`` or no
    arrays, and ``TypeError`` for a card that JSON cannot hold (a numpy
    array, say: give ``.tolist()``); either before any file is touched, so
    that an earlier data set at ``path`` and its card stay as they were.
    """
    target = Path(path)
    if target.suffix != ".npz":
        raise ValueError(f"{target}: a data set file ends in .npz")
    if not arrays:
        raise ValueError("no arrays to save")
    full = dict(card)
    try:
        json.dumps(full, sort_keys=True)
    except (TypeError, ValueError) as e:
        raise TypeError(f"{card_path(target)}: the card must hold only what JSON can: {e}") from e
    savez = np.savez_compressed if compress else np.savez
    write_atomically(target, lambda f: savez(f, **dict(arrays)))
    full.update(file=target.name, bytes=target.stat().st_size, sha256=sha256(target))
    text = json.dumps(full, indent=2, sort_keys=True) + "\n"
    write_atomically(card_path(target), lambda f: f.write(text.encode()))
    return target


def load(path: str | os.PathLike[str], *, verify: bool = True) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Reads a data set written by ``save``: its arrays and its card.

    Raises ``FileNotFoundError`` when the file or its card is missing, and
    ``ValueError`` when ``verify`` and the file's SHA-256 is not the card's.
    """
    target = Path(path)
    card = json.loads(card_path(target).read_text())
    if verify and card.get("sha256") != sha256(target):
        raise ValueError(f"{target}: SHA-256 does not match its card {card_path(target)}")
    with np.load(target) as data:
        arrays = {name: data[name] for name in data.files}
    return arrays, card
