"""The public forward of a model for consumers (motion, export, view, fit): :func:`evaluate`.

Consumers call this instead of reaching into a front end's private setup: it takes a model of either front
end (``smplcore.create(...)`` or ``smplcore.BodyModel``), keyword parameters (NumPy or torch) and optionally the
model's arrays converted once to another namespace (:func:`model_arrays`, e.g. torch tensors for a NumPy model),
and returns the typed :class:`~smplcore.frontend.evaluate.Evaluation` (every position translated)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from smplcore.frontend.evaluate import ArraySource, Evaluation
from smplcore.frontend.evaluate import evaluate as _evaluate

__all__ = ["Evaluation", "evaluate", "model_arrays"]

Outputs = Literal["mesh", "joints"]


def _setup_of(model: Any) -> Any:
    setup = getattr(model, "setup", None)
    if setup is None or not hasattr(setup, "spec"):
        raise TypeError(
            f"model: expected a model of smplcore.create() or a smplcore.BodyModel, got {type(model).__name__}"
        )
    return setup


def model_arrays(model: Any, convert: Callable[[np.ndarray], Any]) -> ArraySource:
    """The arrays of ``model`` (options applied) through ``convert`` (e.g. to torch tensors of a dtype), built on
    first use; pass it to :func:`evaluate` as ``arrays``."""
    from smplcore.frontend.sources import SetupArrays

    return SetupArrays(_setup_of(model), convert)


def evaluate(
    model: Any,
    params: dict[str, Any],
    *,
    outputs: Outputs = "mesh",
    arrays: ArraySource | None = None,
    rotation_matrices: bool = False,
    kernel: str = "auto",
    check_finite: bool = True,
    like: Any = None,
) -> Evaluation:
    """Pose ``model``.

    Parameters
    ----------
    model : a torch module of :func:`smplcore.create` or a :class:`smplcore.BodyModel`.
    params : ``betas``, ``expression``, ``dmpls``, ``transl`` and the pose blocks (``model.rig.pose_blocks``),
        (B, width) each; missing ones are zero.
    outputs : ``"mesh"`` (vertices and joints) or ``"joints"`` (the output joints only, no mesh built).
    arrays : the model's arrays in the namespace of ``params`` (:func:`model_arrays`); None: the model's own.
    rotation_matrices : the pose blocks are (B, n, 3, 3) rotation matrices.
    kernel, check_finite : as the front ends' (see :mod:`smplcore.engine.kernels`).
    like : an array giving namespace, dtype and device when every parameter is None.
    """
    if outputs not in ("mesh", "joints"):
        raise ValueError(f"outputs: expected 'mesh' or 'joints', got {outputs!r}")
    source = arrays if arrays is not None else model.source
    return _evaluate(
        _setup_of(model),
        source,
        params,
        rotation_matrices=rotation_matrices,
        vertices=outputs == "mesh",
        like=like,
        kernel=kernel,
        check_finite=check_finite,
    )
