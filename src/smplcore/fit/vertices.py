"""Fit a model to vertices in correspondence (and optionally its joints): closed form, then exact."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.fit.body import FitBody
from smplcore.fit.gauss_newton import refine
from smplcore.fit.initialize import initialize
from smplcore.fit.result import FitResult, as_array, params_to_state, single_threaded_blas, state_to_params
from smplcore.fit.solver import Objective, State

# Above this many points the initialiser and the first iterations run on an even subset (the last ones
# on all points); the Gauss-Newton matrix always comes from a smaller subset (spread, plus the points
# each joint moves most).
_SUBSET_POINTS = 300
_PER_PART = 4
_HESSIAN_EVERY = 3
_FULL_PER_PART = 25


def _weights(value: Any, name: str, batch: int, count: int) -> np.ndarray:
    if value is None:
        return np.ones((batch, count))
    w = as_array(value, name)
    if w.ndim == 1:
        w = w[None]
    if w.shape[-1] != count or w.shape[0] not in (1, batch) or w.ndim != 2:
        raise ShapeError(f"{name}: expected ({count},) or ({batch}, {count}), got {tuple(np.shape(value))}")
    if np.any(w < 0):
        raise ValueError(f"{name}: weights must be non-negative")
    return np.broadcast_to(w, (batch, count)).copy()


def coefficient_masks(body: FitBody, fit_betas: bool, fit_expression: bool, share_betas: bool):
    """(K,) fitted and (K,) shared masks over [betas, expression]."""
    free = np.zeros(body.num_coeffs, bool)
    free[: body.num_betas] = fit_betas
    free[body.num_betas :] = fit_expression
    shared = np.zeros(body.num_coeffs, bool)
    shared[: body.num_betas] = share_betas and fit_betas
    return free, shared


def even_subset(count: int, size: int) -> np.ndarray:
    """``size`` indices spread evenly over ``range(count)``."""
    if count <= size:
        return np.arange(count)
    return np.unique(np.linspace(0, count - 1, size).round().astype(np.int64))


def spread_subset(body: FitBody, point_ids: np.ndarray, size: int, per_part: int = 12) -> np.ndarray:
    """Rows of ``point_ids``: ``size`` spread evenly, plus the ``per_part`` points most weighted by each joint."""
    n = len(point_ids)
    if n <= size:
        return np.arange(n)
    rows = [even_subset(n, size)]
    main = body.joints[point_ids, 0]
    strength = body.weights[point_ids, 0]
    for j in range(body.num_joints):
        mine = np.flatnonzero(main == j)
        if len(mine):
            rows.append(mine[np.argsort(-strength[mine], kind="stable")[:per_part]])
    return np.unique(np.concatenate(rows))


def part_sample(body: FitBody, point_ids: np.ndarray, weights: np.ndarray, per_part: int) -> tuple:
    """A stratified sample for the Gauss–Newton matrix: up to ``per_part`` points of each part (the points a
    joint moves most), spread over the part, each weighted by its part's total weight over the sample's,
    so that every part counts in the sample as much as in the whole set. Joint targets all stay.

    Returns rows (s,) into ``point_ids`` and their weights (B, s).
    """
    mesh = point_ids < body.num_vertices
    main = np.where(mesh, body.joints[point_ids, 0], -1)
    rows, scale = [np.flatnonzero(~mesh)], [np.ones((len(weights), int((~mesh).sum())))]
    for j in range(body.num_joints):
        mine = np.flatnonzero(main == j)
        if not len(mine):
            continue
        pick = mine[even_subset(len(mine), per_part)]
        total, kept = weights[:, mine].sum(1), weights[:, pick].sum(1)
        rows.append(pick)
        scale.append(np.broadcast_to((total / np.maximum(kept, 1e-300))[:, None], (len(weights), len(pick))))
    order = np.concatenate(rows)
    factor = np.concatenate(scale, axis=1)
    return order, weights[:, order] * factor


def working_dtype(model: Any) -> type:
    """float32 for float32 models (the products over points run twice as fast), else float64."""
    name = str(getattr(model, "dtype", "float64"))
    return np.float32 if name.endswith("float32") else np.float64


def solve(
    body: FitBody,
    point_ids: np.ndarray,
    targets: np.ndarray,
    weights: np.ndarray,
    start: State,
    *,
    free: np.ndarray,
    shared: np.ndarray,
    fit_transl: bool,
    shape_prior: float,
    pose_prior: np.ndarray | None,
    init_iterations: int,
    max_iter: int,
    tol: float,
    dtype: type = np.float64,
) -> tuple[State, np.ndarray, np.ndarray, int]:
    """Initialiser and LM on a subset of the points, then LM on all of them (both with the Gauss–Newton
    matrix of a smaller subset). Returns the state, (B, n) point distances, converged flags, iterations."""

    def objective(rows: np.ndarray, w: np.ndarray | None = None) -> Objective:
        return Objective(
            body.points(point_ids[rows]),
            targets[:, rows],
            weights[:, rows] if w is None else w,
            free,
            shared,
            fit_transl,
            shape_prior,
            pose_prior,
        )

    n = len(point_ids)
    joint_rows = np.flatnonzero(point_ids >= body.num_vertices)
    subset = np.union1d(spread_subset(body, point_ids, _SUBSET_POINTS, _PER_PART), joint_rows)
    sub = objective(subset)
    state = start
    if init_iterations:
        state = initialize(body, sub, state, iterations=init_iterations)
    iterations = 0
    if len(subset) < n:
        state, _, _, _, iterations = refine(
            body, sub, state, dtype=dtype, max_iter=max_iter, tol=tol, hessian_every=_HESSIAN_EVERY
        )
    # the whole set: its Gauss-Newton matrix from a sample of every part weighted as the part (computed
    # once: exact targets stop at the first evaluation, noisy ones need a few gradient steps)
    h_rows, h_w = part_sample(body, point_ids, weights, _FULL_PER_PART)
    h_all = objective(h_rows, h_w) if len(subset) < n and len(h_rows) < n else None  # few points: exact
    state, _, dist, converged, more = refine(
        body,
        objective(np.arange(n)),
        state,
        hessian_obj=h_all,
        dtype=dtype,
        max_iter=max_iter,
        tol=tol,
        hessian_every=max_iter if h_all is not None else _HESSIAN_EVERY,
    )
    return state, dist, converged, iterations + more


@single_threaded_blas
def fit_vertices(
    model: Any,
    vertices: Any,
    joints: Any = None,
    vertex_weights: Any = None,
    joint_weights: Any = None,
    *,
    vertex_ids: Any = None,
    betas: Any = None,
    fit_betas: bool = True,
    fit_expression: bool = True,
    share_betas: bool = False,
    fit_transl: bool = True,
    shape_prior: float = 0.0,
    pose_prior: float = 0.0,
    init: dict[str, Any] | None = None,
    init_iterations: int = 3,
    max_iter: int = 30,
    tol: float = 1e-6,
) -> FitResult:
    """Parameters of ``model`` whose mesh matches vertices in correspondence.

    Parameters
    ----------
    model : a torch model of :func:`smplcore.create` or a :class:`smplcore.BodyModel`.
    vertices : (B, V, 3) target vertices (metres), or (B, n, 3) with ``vertex_ids``.
    joints : optional (B, n_j, 3) targets for the first n_j skeleton joints.
    vertex_weights, joint_weights : (n,) or (B, n) non-negative weights (default 1).
    vertex_ids : (n,) the model vertices the targets belong to (default: all).
    betas : starting (or, with ``fit_betas=False``, fixed) betas, (n_b,) or (B, n_b).
    fit_betas, fit_expression : fit the betas / expression coefficients (models with expression).
    share_betas : one set of betas for the whole batch (one person in many frames).
    fit_transl : fit the translation (else it stays at ``init``'s, or zero).
    shape_prior : weight of Σ β² added to the squared error (m²); 0 fits the data exactly.
    pose_prior : weight of Σ θ² over the pose parameters but the global orientation (towards the rest pose).
    init : forward keywords to start from (default: the closed-form initialiser from zero).
    init_iterations : rounds of the closed-form initialiser (0: start from ``init`` as is).
    max_iter, tol : Levenberg–Marquardt iterations per stage and relative cost decrease to stop at.

    Returns
    -------
    FitResult with ``params``, ``vertex_error`` (B,) and ``joint_error`` (B,) (with ``joints``).

    Examples
    --------
    >>> import numpy as np, smplcore
    >>> from smplcore import fit
    >>> model = smplcore.BodyModel(model_type="open")
    >>> target = model(body_pose=np.full((1, 69), 0.1), betas=np.ones((1, 10))).vertices
    >>> r = fit.fit_vertices(model, target)
    >>> bool(r.vertex_error[0] < 1e-4)
    True
    """
    body = FitBody.from_model(model)
    ids = np.arange(body.num_vertices) if vertex_ids is None else np.asarray(vertex_ids, np.int64).reshape(-1)
    if ids.size and (ids.min() < 0 or ids.max() >= body.num_vertices):
        raise ValueError(f"vertex_ids: indices must be in [0, {body.num_vertices})")
    verts = as_array(vertices, "vertices")
    if verts.ndim == 2:
        verts = verts[None]
    if verts.ndim != 3 or verts.shape[1:] != (len(ids), 3):
        raise ShapeError(f"vertices: expected (B, {len(ids)}, 3), got {tuple(np.shape(vertices))}")
    batch = verts.shape[0]
    id_parts, target_parts = [ids], [verts]
    w = [_weights(vertex_weights, "vertex_weights", batch, len(ids))]
    n_joints = 0
    if joints is not None:
        jt = as_array(joints, "joints")
        if jt.ndim == 2:
            jt = jt[None]
        if jt.ndim != 3 or jt.shape[0] != batch or jt.shape[2] != 3 or jt.shape[1] > body.num_joints:
            raise ShapeError(
                f"joints: expected ({batch}, n, 3) with n <= {body.num_joints} skeleton joints, got {tuple(jt.shape)}"
            )
        n_joints = jt.shape[1]
        id_parts.append(body.num_vertices + np.arange(n_joints))
        target_parts.append(jt)
        w.append(_weights(joint_weights, "joint_weights", batch, n_joints))
    point_ids, targets, weights = np.concatenate(id_parts), np.concatenate(target_parts, 1), np.concatenate(w, 1)
    if len(point_ids) < 3 or not np.all(weights.sum(1) > 0):
        raise ValueError("vertices: need at least 3 points with positive weight per body")
    start = params_to_state(body, {**(init or {}), **({} if betas is None else {"betas": betas})}, batch)
    free, shared = coefficient_masks(body, fit_betas, fit_expression, share_betas)
    pose_w = body.pose_prior_weights(pose_prior)
    state, dist, converged, iterations = solve(
        body,
        point_ids,
        targets,
        weights,
        start,
        free=free,
        shared=shared,
        fit_transl=fit_transl,
        shape_prior=shape_prior,
        pose_prior=pose_w,
        init_iterations=init_iterations,
        max_iter=max_iter,
        tol=tol,
        dtype=working_dtype(model),
    )
    return FitResult(
        params=state_to_params(body, model, state),
        vertex_error=dist[:, : len(ids)].mean(1),
        joint_error=dist[:, len(ids) :].mean(1) if n_joints else None,
        converged=converged,
        iterations=iterations,
    )
