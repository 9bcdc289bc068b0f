"""Fit a model to vertices in correspondence (and optionally its joints): closed form, then exact."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.fit import checks
from smplcore.fit.body import FitBody, pose_points
from smplcore.fit.gauss_newton import refine
from smplcore.fit.initialize import initialize
from smplcore.fit.parallel import chunks, map_chunks
from smplcore.fit.plausibility import Plausibility, assess
from smplcore.fit.prior_terms import PoseTerms
from smplcore.fit.result import (
    FitResult,
    as_array,
    is_torch_model,
    params_to_state,
    single_threaded_blas,
    state_to_params,
)
from smplcore.fit.solver import Objective, State

# The initialiser and the first iterations run on a subset: _PER_PART points of each part (those its joint
# moves most) and _SUBSET_POINTS spread evenly, with that subset's exact Gauss-Newton matrix (refreshed
# every _HESSIAN_EVERY iterations, and after a far step). The whole set's iterations (noisy targets) take
# their matrix from _FULL_PER_PART points of each part.
_SUBSET_POINTS = 64
_PER_PART = 8
_HESSIAN_EVERY = 3
_FULL_PER_PART = 25
# The subset stage of noisy targets stops once an iteration gains less than this (the whole-set stage
# finishes); exact targets reach the precision's floor first (the decrease stays near 100 % until then).
_SUBSET_TOL = 1e-2


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


def _take(a: np.ndarray, bodies: Any, rows: np.ndarray) -> np.ndarray:
    """``a[bodies][:, rows]`` in one gather (``a[bodies]`` alone would copy every point of those bodies)."""
    if isinstance(bodies, slice):
        return a[bodies][:, rows]
    return a[np.ix_(np.asarray(bodies), rows)]


def working_dtype(model: Any) -> type:
    """float32 for float32 models (the products over points run twice as fast), else float64."""
    name = str(getattr(model, "dtype", "float64"))
    return np.float32 if name.endswith("float32") else np.float64


def model_distances(model: Any, body: FitBody, state: State, point_ids: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(B, n) distances between ``targets`` (B, n, 3) and the points ``point_ids`` (vertices, then skeleton
    joints offset by V) of ``model`` posed by ``state``: the vertices from the model's own forward (the
    fastest whole-mesh evaluation there is), the joints from the kinematic chain (a model's ``joint_mapper``
    may reorder its output joints), in the targets' precision."""
    params = state_to_params(body, model, state)
    if is_torch_model(model):
        import torch

        with torch.no_grad():
            verts = model(**params).vertices.cpu().numpy()
    else:
        verts = model(**params).vertices
    num_verts = body.num_vertices
    if len(point_ids) == num_verts and np.array_equal(point_ids, np.arange(num_verts)):
        diff = verts - targets
    else:
        mesh = point_ids < num_verts
        diff = np.empty(targets.shape, targets.dtype)
        diff[:, mesh] = verts[:, point_ids[mesh]]
        if not mesh.all():
            joints = body.points(point_ids[~mesh])
            diff[:, ~mesh] = pose_points(body, joints, body.full_pose(state.pose), state.coeffs, state.transl).points
        diff -= targets
    np.square(diff, out=diff)  # summed coordinate by coordinate: 3× faster than einsum over a last axis of 3
    dist = diff[..., 0] + diff[..., 1]
    dist += diff[..., 2]
    return np.sqrt(dist, out=dist)


def regressed_joints(body: FitBody, point_ids: np.ndarray, targets: np.ndarray, weights: np.ndarray):
    """(B, J, 3) the joint regressor applied to the target vertices — the posed skeleton to a few
    millimetres — when the targets hold every vertex it reads (with positive weight), else None."""
    reg = body.regressor
    needed = np.unique(reg.indices)
    at = np.full(body.num_vertices, -1)
    mesh = np.flatnonzero(point_ids < body.num_vertices)
    at[point_ids[mesh]] = mesh
    rows = at[needed]
    if np.any(rows < 0) or np.any(weights[:, rows] <= 0):
        return None
    dtype = targets.dtype
    # (3 m, 3 J): the regressor acting on the coordinates of the m vertices it reads, one by one
    matrix = body.cached(("regressor", dtype.str), lambda: np.kron(reg[:, needed].T.toarray(), np.eye(3)).astype(dtype))
    coords = (3 * rows[:, None] + np.arange(3)).ravel()
    picked = np.take(targets.reshape(len(targets), -1), coords, axis=1)  # (B, 3 m)
    return (picked @ matrix).reshape(len(targets), -1, 3).astype(np.float64)


def _floor(dtype: type) -> float:
    """Cost per unit weight (m²) of a fit as exact as the working precision allows: RMS 0.2 µm in
    float64, 2 µm in float32 (whose posed vertices alone are good to ~0.5 µm)."""
    return 4e-14 if np.dtype(dtype) == np.float64 else 4e-12


def solve(
    model: Any,
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
    pose_terms: Any = None,
    max_iter: int,
    tol: float,
    dtype: type = np.float64,
    workers: int | None = 1,
    exact: bool = True,
) -> tuple[State, np.ndarray | None, np.ndarray, int]:
    """Initialiser and LM on a subset of the points (its exact Gauss–Newton matrix), then, when ``exact``,
    the whole set: bodies whose whole-set cost is already at the working precision's floor are done, the
    others run LM on all points (gradient over all of them, Gauss–Newton matrix from a sample of every
    part). Returns the state, (B, n) point distances (None where the whole set was never posed: the
    closed form alone, or ``exact=False``), converged flags and iterations."""

    def objective(rows: np.ndarray, w: np.ndarray | None = None, bodies: Any = slice(None)) -> Objective:
        prior = pose_prior[bodies] if pose_prior is not None and pose_prior.ndim == 2 else pose_prior
        return Objective(
            body.points(point_ids[rows]),
            _take(targets, bodies, rows),
            (_take(weights, bodies, rows) if w is None else w),
            free,
            shared,
            fit_transl,
            shape_prior,
            prior,
            pose_terms=pose_terms,
        )

    n = len(point_ids)
    joint_rows = np.flatnonzero(point_ids >= body.num_vertices)
    subset = np.union1d(spread_subset(body, point_ids, _SUBSET_POINTS, _PER_PART), joint_rows)
    whole = len(subset) == n
    batch = len(targets)
    state = start.copy()
    converged = np.zeros(batch, bool)
    dist = np.empty((batch, n), targets.dtype)
    joints = regressed_joints(body, point_ids, targets, weights)  # bone ends for the initial rotations

    def subset_stage(rows: np.ndarray) -> int:
        """Initialiser and LM on the subset (on every point when the subset is all of them)."""
        sub = objective(subset, bodies=rows)
        part = state.take(rows)
        if init_iterations:
            guess = None if joints is None else joints[rows]
            part = initialize(body, sub, part, iterations=init_iterations, dtype=dtype, joints=guess)
        if not max_iter:  # the closed form alone: measured on every point below
            state.put(rows, part)
            return 0
        part, _, part_dist, converged[rows], its = refine(
            body,
            sub,
            part,
            dtype=dtype,
            max_iter=max_iter,
            tol=tol if whole or not exact else max(tol, _SUBSET_TOL),
            hessian_every=_HESSIAN_EVERY,
        )
        state.put(rows, part)
        if whole:
            dist[rows] = part_dist
        return its

    parts = [np.arange(batch)] if shared.any() else chunks(batch, workers)
    iterations = max(map_chunks(subset_stage, parts, workers))
    if whole and max_iter:
        return state, dist, converged, iterations
    if not (max_iter and exact):  # the closed form, or the subset's fit: measured only when asked for
        return state, None, converged, iterations
    # the whole set: bodies already at the working precision's floor are done (exact targets); the others
    # run LM on all points with the Gauss-Newton matrix of a sample of every part weighted as the part
    # (recomputed only after a failed or far step: the subset's optimum is close)
    dist[:] = model_distances(model, body, state, point_ids, targets)
    cost = np.einsum("bn,bn,bn->b", weights, dist, dist, dtype=np.float64)
    todo = cost > _floor(dtype) * weights.sum(1)
    if shared.any() and todo.any():
        todo[:] = True  # shared coefficients couple the bodies
    if not todo.any():
        return state, dist, converged | ~todo, iterations
    bodies = np.flatnonzero(todo)
    h_rows, h_w = part_sample(body, point_ids, weights[bodies], _FULL_PER_PART)
    part, _, dist[bodies], converged[bodies], more = refine(
        body,
        objective(np.arange(n), bodies=bodies),
        state.take(bodies),
        hessian_obj=objective(h_rows, h_w, bodies=bodies),
        dtype=dtype,
        max_iter=max_iter,
        tol=tol,
        hessian_every=max_iter,
        workers=workers,
    )
    state.put(bodies, part)
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
    joint_limits: float = 0.0,
    init: dict[str, Any] | None = None,
    init_iterations: int = 3,
    max_iter: int = 30,
    tol: float = 1e-6,
    exact: bool = True,
    workers: int | None = None,
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
    joint_limits : weight (m² per rad²) of the anatomical joint limits (:data:`smplcore.fit.priors.JOINT_LIMITS`),
        against the squared distances of all the points (100 holds a limit against a whole mesh of 6,890
        vertices); 0 (the default): a mesh is reproduced as it is, and ``plausibility`` reports its joints.
    init : forward keywords to start from (default: the closed-form initialiser from zero).
    init_iterations : rounds of the closed-form initialiser (0: start from ``init`` as is).
    max_iter, tol : Levenberg–Marquardt iterations per stage and relative cost decrease to stop at
        (``max_iter=0``: the closed form alone).
    exact : finish with Levenberg–Marquardt on every target point (the exact optimum); False stops after
        the iterations on a sample of ~250 well-spread points (a few millimetres from the optimum on
        noise-free targets, several times faster: ``max_iter=1`` is the fast setting).
    workers : threads solving independent chunks of bodies (None: one per core; 1: this thread only).

    Returns
    -------
    FitResult with ``params``, ``vertex_error`` (B,) and ``joint_error`` (B,) (with ``joints``); without
    the whole-set stage (``max_iter=0`` or ``exact=False``) the errors are measured when first read.
    ``mask`` (B, n_v + n_j) marks the targets used (positive weight) and ``point_error`` (B, n_v + n_j)
    gives each one's distance (metres; NaN where unused; None without the whole-set stage);
    ``plausibility`` reports joints outside their anatomical limits (no warning: the targets decide).

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
    shape_prior, pose_prior, joint_limits = checks.options(
        "weight", {"shape_prior": shape_prior, "pose_prior": pose_prior, "joint_limits": joint_limits}
    ).values()
    tol = checks.positive("tol", tol)
    max_iter, init_iterations = checks.options(
        "iterations", {"max_iter": max_iter, "init_iterations": init_iterations}
    ).values()
    workers = checks.workers(workers)
    init = checks.init_params(init, body)
    ids = np.arange(body.num_vertices) if vertex_ids is None else _vertex_ids(vertex_ids)
    if ids.size and (ids.min() < 0 or ids.max() >= body.num_vertices):
        raise ValueError(f"vertex_ids: indices must be in [0, {body.num_vertices})")
    dtype = working_dtype(model)
    verts = as_array(vertices, "vertices", dtype)
    if verts.ndim == 2:
        verts = verts[None]
    if verts.ndim != 3 or verts.shape[1:] != (len(ids), 3):
        raise ShapeError(f"vertices: expected (B, {len(ids)}, 3), got {tuple(np.shape(vertices))}")
    batch = verts.shape[0]
    checks.nonempty_batch("vertices", batch)
    id_parts, target_parts = [ids], [verts]
    w = [_weights(vertex_weights, "vertex_weights", batch, len(ids))]
    n_joints = 0
    if joints is not None:
        jt = as_array(joints, "joints", dtype)
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
    point_ids, weights = np.concatenate(id_parts), np.concatenate(w, 1)
    targets = verts if len(target_parts) == 1 else np.concatenate(target_parts, 1)
    if len(point_ids) < 3 or not np.all((weights > 0).sum(1) >= 3):
        raise ValueError("vertices, vertex_weights: need at least 3 points with positive weight per body")
    checks.check_scale("vertices", verts, _rest_vertices(body, ids), weights[:, : len(ids)] > 0)
    start = params_to_state(body, {**(init or {}), **({} if betas is None else {"betas": betas})}, batch)
    free, shared = coefficient_masks(body, fit_betas, fit_expression, share_betas)
    pose_w = body.pose_prior_weights(pose_prior)
    state, dist, converged, iterations = solve(
        model,
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
        pose_terms=PoseTerms.of(body, joint_limits, 0.0),
        init_iterations=init_iterations,
        max_iter=max_iter,
        tol=tol,
        dtype=dtype,
        workers=workers,
        exact=exact,
    )

    def errors(dist: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        return dist[:, : len(ids)].mean(1), (dist[:, len(ids) :].mean(1) if n_joints else None)

    if dist is None:
        kept = targets.copy()  # may share the caller's array, which may change before the errors are read

        def measure() -> tuple[np.ndarray, np.ndarray | None]:
            out = errors(model_distances(model, body, state, point_ids, kept))
            if not all(e is None or np.all(np.isfinite(e)) for e in out):
                raise checks.FitError("fit_vertices: the fitted bodies' errors came out non-finite")
            return out

        result = FitResult(
            params=state_to_params(body, model, state),
            converged=converged,
            iterations=iterations,
            mask=weights > 0,
            plausibility=_plausibility(body, state),
            measure=measure,
        )
        return checks.finite_result(result, "fit_vertices")
    vertex_error, joint_error = errors(dist)
    spread = checks.spread_of(verts, weights[:, : len(ids)] > 0)
    converged = checks.flag_gross(converged, vertex_error, spread, "fit_vertices", "m")
    mask = weights > 0
    result = FitResult(
        params=state_to_params(body, model, state),
        vertex_error=vertex_error,
        joint_error=joint_error,
        converged=converged,
        iterations=iterations,
        point_error=np.where(mask, dist, np.nan),
        mask=mask,
        plausibility=_plausibility(body, state),
    )
    return checks.finite_result(result, "fit_vertices")


def _plausibility(body: FitBody, state: State) -> Plausibility:
    """The fitted bodies' joints against their anatomical limits (reported, not warned about: the target
    mesh decides the pose)."""
    block = next((b for b in body.blocks if b.name == "body_pose"), None)
    pose = state.pose[:, :0] if block is None else state.pose[:, block.start : block.start + block.width]
    return assess(body, pose)


def _vertex_ids(value: Any) -> np.ndarray:
    """(n,) int64 vertex ids from integer-valued input; a TypeError naming ``vertex_ids`` otherwise."""
    array = np.asarray(value.detach().cpu().numpy() if hasattr(value, "detach") else value)
    if array.dtype.kind not in "iu" and not (array.dtype.kind == "f" and np.all(np.mod(array, 1) == 0)):
        raise TypeError(f"vertex_ids: expected integer vertex indices, got {array.dtype} values")
    return array.astype(np.int64).reshape(-1)


def _rest_vertices(body: FitBody, ids: np.ndarray) -> np.ndarray:
    """(n, 3) the rest body's vertices ``ids`` (the template)."""
    return np.asarray(body.template, np.float64)[ids]
