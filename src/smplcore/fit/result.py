"""The result of a fit, and the conversion between solver states and the model's forward keywords."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.fit.body import FitBody
from smplcore.fit.plausibility import Plausibility
from smplcore.fit.solver import State
from smplcore.model.params import fit_width


class FitResult:
    """What a fit found.

    Attributes
    ----------
    params : the model's forward keywords (``betas``, ``global_orient``, ``body_pose``, the hand, jaw and
        eye blocks, ``expression``, ``transl``) as arrays of the model's kind (torch tensors for a torch
        model, NumPy arrays for a :class:`smplcore.BodyModel`), batch first; ``model(**r.params)``
        reproduces the fit.
    vertex_error : (B,) mean distance (metres) between the fitted and the target vertices, or None.
    joint_error : (B,) mean distance (metres) between the fitted and the target joints, or None.
    reprojection_error : (B,) mean distance (pixels) of the projected keypoints, or None.
    point_error : (B, n) distance of each target point from the fitted body's (metres for 3D targets, pixels
        for 2D keypoints), NaN where the point was not used (zero weight, missing marker), or None.
    mask : (B, n) bool, the target points the fit used (positive weight, finite), or None.
    converged : (B,) whether the optimiser stopped because it converged (relative cost decrease or step
        below its tolerance), not because it ran out of iterations, and the body is not grossly far from
        its targets (:func:`smplcore.fit.checks.flag_gross`).
    plausibility : a :class:`~smplcore.fit.plausibility.Plausibility` (which body joints lie outside their
        anatomical limits, by how many degrees per axis), or None.
    bones : for a fit of 3D joints, a :class:`smplcore.skeletons.BoneReport` (the targets' bone lengths against
        what the model's shape space reaches; ``print(r.bones)`` for the table), or None.
    iterations : refinement iterations run.
    camera : a 2D fit's :class:`~smplcore.fit.Camera` (with the estimated focal length when it was
        estimated), or None.

    A fit that never posed the whole mesh (``fit_vertices(..., max_iter=0)`` or ``exact=False``) measures
    ``vertex_error`` and ``joint_error`` on first access (one forward pass of the model), so that a caller
    who needs only the parameters does not pay for it.
    """

    def __init__(
        self,
        params: dict[str, Any],
        vertex_error: np.ndarray | None = None,
        joint_error: np.ndarray | None = None,
        reprojection_error: np.ndarray | None = None,
        converged: np.ndarray | None = None,
        iterations: int = 0,
        camera: Any = None,
        *,
        point_error: np.ndarray | None = None,
        mask: np.ndarray | None = None,
        plausibility: Plausibility | None = None,
        bones: Any = None,
        measure: Callable[[], tuple[np.ndarray | None, np.ndarray | None]] | None = None,
    ) -> None:
        self.params = params
        self._vertex_error, self._joint_error = vertex_error, joint_error
        self._measure = measure
        self.reprojection_error = reprojection_error
        self.converged = np.zeros(0, bool) if converged is None else converged
        self.iterations = iterations
        self.camera = camera
        self.point_error, self.mask, self.plausibility = point_error, mask, plausibility
        self.bones = bones

    def _measured(self) -> None:
        if self._measure is not None:
            self._vertex_error, self._joint_error = self._measure()
            self._measure = None

    @property
    def vertex_error(self) -> np.ndarray | None:
        self._measured()
        return self._vertex_error

    @vertex_error.setter
    def vertex_error(self, value: np.ndarray | None) -> None:
        measure = self._measure
        if measure is not None:  # the joints' error is still to be measured
            self._measure = lambda: (value, measure()[1])
        self._vertex_error = value

    @property
    def joint_error(self) -> np.ndarray | None:
        self._measured()
        return self._joint_error

    @joint_error.setter
    def joint_error(self, value: np.ndarray | None) -> None:
        measure = self._measure
        if measure is not None:
            self._measure = lambda: (measure()[0], value)
        self._joint_error = value

    @property
    def all_converged(self) -> bool:
        return bool(np.all(self.converged))

    @property
    def plausible(self) -> np.ndarray | None:
        """(B,) whether each body's joints lie within their anatomical limits (see :attr:`plausibility`),
        or None when the fit did not assess them."""
        return None if self.plausibility is None else self.plausibility.plausible

    def __repr__(self) -> str:
        def show(value: Any) -> str:
            return "None" if value is None else f"array(shape={tuple(np.shape(value))})"

        errors = (
            "vertex_error=<measured on access>, joint_error=<measured on access>"
            if self._measure is not None
            else f"vertex_error={show(self._vertex_error)}, joint_error={show(self._joint_error)}"
        )
        return (
            f"FitResult(params={sorted(self.params)}, {errors}, reprojection_error={show(self.reprojection_error)}, "
            f"converged={int(np.sum(self.converged))}/{len(self.converged)}, iterations={self.iterations}, "
            f"camera={self.camera!r}"
            + (
                ""
                if self.plausibility is None
                else f", plausible={self.plausibility.plausible.sum()}/{len(self.converged)}"
            )
            + ")"
        )


def single_threaded_blas(fn: Callable) -> Callable:
    """Run ``fn`` with one BLAS thread when threadpoolctl is installed: the solver makes many small
    products (one per body), where OpenBLAS's thread start-up costs more than the work (20x on a busy
    2-core machine)."""

    @functools.wraps(fn)
    def run(*args: Any, **kwargs: Any) -> Any:
        controller = _blas_controller()
        if controller is None:  # optional: without threadpoolctl BLAS keeps its own threading
            return fn(*args, **kwargs)
        with controller.limit(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return run


@functools.cache
def _blas_controller() -> Any:
    """threadpoolctl's view of the loaded thread pools, found once (a search of the loaded libraries)."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


def is_torch_model(model: Any) -> bool:
    """Whether ``model`` is a torch module (without importing torch when it is not loaded)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(model, torch.nn.Module)


def as_array(value: Any, name: str, dtype: Any = np.float64) -> np.ndarray:
    """``value`` (NumPy, torch, nested lists) as a finite NumPy array of ``dtype`` (float64 by default; not
    copied when it already is one); errors name ``name``."""
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    try:
        array = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{name}: expected a numeric array, got {type(value).__name__}") from exc
    if not np.all(np.isfinite(array)):
        bad = int(np.sum(~np.isfinite(array)))
        raise ValueError(f"{name}: {bad} non-finite value(s) (NaN or inf); remove them or give them zero weight")
    return array


def state_to_params(body: FitBody, model: Any, state: State) -> dict[str, Any]:
    """The forward keywords of ``model`` for a solver state."""
    params: dict[str, np.ndarray] = {}
    for block in body.blocks:
        params[block.name] = state.pose[:, block.start : block.start + block.width]
    params["betas"] = state.coeffs[:, : body.num_betas]
    if body.num_expression:
        params["expression"] = state.coeffs[:, body.num_betas :]
    params["transl"] = state.transl
    if is_torch_model(model):
        import torch

        dtype = getattr(model, "dtype", torch.float32)
        device = model.v_template.device if hasattr(model, "v_template") else "cpu"
        return {k: torch.as_tensor(np.ascontiguousarray(v), dtype=dtype, device=device) for k, v in params.items()}
    np_dtype: Any = getattr(model, "dtype", np.float32)
    return {k: np.ascontiguousarray(v, dtype=np_dtype) for k, v in params.items()}


def params_to_state(body: FitBody, params: dict[str, Any], batch: int) -> State:
    """A solver state from forward keywords (missing ones zero; batch 1 broadcast)."""

    def rows(name: str, width: int) -> np.ndarray:
        value = params.get(name)
        if value is None:
            return np.zeros((batch, width))
        array = as_array(value, name)
        if array.ndim == 1:
            array = array[None]
        array = array.reshape(array.shape[0], -1)
        if name in ("betas", "expression"):  # the one coefficient rule (smplcore.model.params)
            array = fit_width(name, array, width)
        if array.shape[1] != width or array.shape[0] not in (1, batch):
            raise ShapeError(f"{name}: expected ({batch}, {width}), got {tuple(array.shape)}")
        return np.broadcast_to(array, (batch, width)).copy()

    pose = np.concatenate([rows(b.name, b.width) for b in body.blocks], axis=1)
    coeffs = rows("betas", body.num_betas)
    if body.num_expression:
        coeffs = np.concatenate([coeffs, rows("expression", body.num_expression)], axis=1)
    return State(pose, coeffs, rows("transl", 3))
