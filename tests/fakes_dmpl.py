"""Fake DMPL files (soft-tissue blend shapes), laid out as AMASS ships ``dmpls/<gender>/model.npz``.

The real file holds ``eigvec`` (6890, 3, 8) float arrays; here they are seeded random offsets of a few
millimetres per unit coefficient.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

NUM_DMPLS = 8


def dmpl_eigvec(num_vertices: int = 6890, num_dmpls: int = NUM_DMPLS, seed: int = 0) -> np.ndarray:
    """(V, 3, n) float64 seeded blend shapes, about 5 mm per unit coefficient."""
    rng = np.random.default_rng(1000 + seed)
    return rng.normal(scale=0.005, size=(num_vertices, 3, num_dmpls))


def write_dmpl(
    dirpath: str | Path,
    num_vertices: int = 6890,
    num_dmpls: int = NUM_DMPLS,
    seed: int = 0,
    name: str = "dmpl.npz",
    key: str = "eigvec",
) -> Path:
    """Write a fake DMPL file (``key`` holds :func:`dmpl_eigvec`) and return its path."""
    path = Path(dirpath) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **{key: dmpl_eigvec(num_vertices, num_dmpls, seed)})
    return path


def dmpl_sequence(frames: int, num_dmpls: int = NUM_DMPLS, seed: int = 0) -> np.ndarray:
    """(T, n) smooth per-frame DMPL coefficients, as an AMASS sequence's ``dmpls``."""
    rng = np.random.default_rng(2000 + seed)
    t = np.arange(frames)[:, None] / 10.0
    return np.sin(t * rng.uniform(0.5, 2.0, num_dmpls) + rng.uniform(0, 6.3, num_dmpls)) * rng.uniform(
        0.5, 2.0, num_dmpls
    )
