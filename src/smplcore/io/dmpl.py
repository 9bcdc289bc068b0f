"""DMPL dynamic (soft-tissue) blend shapes: the ``dmpl.npz`` that AMASS and human_body_prior use.

The file holds ``eigvec``: (V, 3, n) vertex offsets, n = 8 in the AMASS release, one column per
coefficient of a sequence's ``dmpls`` (T, n). They are added to the shaped template before posing,
like shape blend shapes (:func:`smplcore.create` / :class:`smplcore.BodyModel` with ``dmpl_path=``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from smplcore.io.checks import Checker

__all__ = ["load_dmpl"]

DMPL_KEY = "eigvec"


def load_dmpl(path: str | Path, num_vertices: int | None = None) -> np.ndarray:
    """The (V, 3, n) float64 DMPL blend shapes of ``path``, read through the safe loader.

    Parameters
    ----------
    path : a ``dmpl.npz`` (or a pickle holding a dict) with the key ``eigvec``.
    num_vertices : the model's vertex count V, checked when given.

    Raises
    ------
    ModelFileError
        naming the file and the key: missing file or key, wrong shape (a vertex count that is not the
        model's), NaN or infinite values, or anything the safe loader refuses.
    """
    from smplcore.errors import ModelFileError
    from smplcore.io import read_arrays

    path = Path(path)
    raw = read_arrays(path, "a DMPL file (dmpl.npz)")
    if not isinstance(raw, Mapping):
        raise ModelFileError(path, f"expected a dict of arrays with the key {DMPL_KEY!r}, found a {type(raw).__name__}")

    def convert(c: Checker) -> np.ndarray:
        value = np.asarray(c.get(DMPL_KEY))  # required: a missing key raises, naming the file's keys
        if value.ndim != 3 or value.shape[1] != 3 or value.shape[2] < 1:
            raise c.error(f"expected shape (V, 3, n) DMPL blend shapes, found {value.shape}", DMPL_KEY)
        if num_vertices is not None and value.shape[0] != num_vertices:
            raise c.error(
                f"expected shape ({num_vertices}, 3, n): the model has {num_vertices} vertices, this file's "
                f"blend shapes have {value.shape[0]}; use the DMPL file made for this model",
                DMPL_KEY,
            )
        return c.expect(DMPL_KEY, value, (value.shape[0], 3, None)).astype(np.float64)

    return Checker(path, raw).run(convert)
