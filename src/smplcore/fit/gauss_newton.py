"""Levenberg–Marquardt with the exact gradient over every point and a Gauss–Newton matrix from a subset.

Each iteration evaluates the cost and the exact gradient ``Jᵀ r`` over all the objective's points with
:mod:`smplcore.fit.dense` (a few matrix products per batch, no dense Jacobian), and takes the Gauss–Newton
matrix ``Jᵀ W J`` of a small, well-spread subset of points (:mod:`smplcore.fit.normal_matrix`, part by
part, scaled to the whole set's weight), recomputed every few iterations and after a step that moved far
or failed. The step is still a descent step and the fixed point is the optimum of the whole objective —
only the convergence rate depends on how well the subset's matrix stands for the whole set's. Bodies
are solved in chunks (independent problems, in threads) unless shape coefficients are shared over the
batch; then the per-body work (cost, gradient, matrix) is split over threads and the step is one system.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from smplcore.fit import dense
from smplcore.fit.body import FitBody
from smplcore.fit.normal_matrix import normal_matrix
from smplcore.fit.parallel import chunks, map_chunks
from smplcore.fit.solver import (
    Objective,
    State,
    _column_map,
    _columns,
    _flat,
    _prior_cost,
    _step,
    _unflat,
)
from smplcore.fit.temporal import temporal_step

# Bodies per chunk: keeps the (n, 3, 3, chunk) working arrays of a 10k-vertex mesh near 100 MB.
_CHUNK_POINTS = 1_500_000
# ... and the (chunk, P, P) Gauss-Newton matrices and (chunk, 3 n, P) Jacobians of a few points (22 joints:
# P = 85) near 30 MB each: memory grows with the batch by what one body's arrays take, not by the batch's
# whole stack at once (4,000 frames of 22 joints took 570 MB above the model; now ~10 % of that).
_CHUNK_VALUES = 4_000_000
# Below this many points × bodies in all, one thread: a thread's start-up per call costs more than the
# work it shares (22 joints of a 64-frame sequence ran 30 % slower in two threads, 256 frames 11 %).
_THREAD_MIN_WORK = 16_384
# A step moving a parameter by more than this (radians, metres, shape units) makes the Gauss-Newton
# matrix stale: it is recomputed at the next iteration.
_FAR = 0.05


class _Problem:
    """The objective's constant arrays, in batch-last layout and the working precision."""

    def __init__(self, body: FitBody, obj: Objective, hessian_obj: Objective | None, dtype: npt.DTypeLike) -> None:
        self.body, self.obj = body, obj
        self.hobj = hessian_obj if hessian_obj is not None else obj
        self.arrays = dense.dense_points(body, obj.points, dtype)
        self.harrays = dense.dense_points(body, self.hobj.points, dtype)
        self.targets = np.ascontiguousarray(np.moveaxis(obj.targets, 0, -1), dtype=dtype)  # (n, 3, B)
        self.weights = np.ascontiguousarray(obj.weights.T, dtype=dtype)  # (n, B)
        cols = _columns(body, obj)
        q, nj = body.num_pose, body.num_joints
        self.select = None  # the Jacobian's columns are the parameters' (axis-angle pose): pick, not multiply
        if body.pose_map is None:
            # joints that move no point (a wrist with 22 joint targets) are left as they are: their only
            # term is the pose prior, whose optimum is its centre, where the initialiser leaves them
            moving = np.zeros(nj + 1, bool)
            moving[obj.points.ancestors] = True
            cols = cols[(cols >= q) | moving[np.minimum(cols // 3, nj)]]
            self.select = None if len(cols) == q + body.num_coeffs + 3 else cols
        self.cols = cols
        self.fitted_pose = np.where(cols < q, cols, -1)  # the pose column of each fitted column (-1: none)
        self.transform = None if body.pose_map is None else _column_map(body, cols)
        self.ratio = obj.weights.sum(1) / np.maximum(self.hobj.weights.sum(1), 1e-300)

    def evaluate(self, state: State, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cost (b,), gradient (b, P) over the fitted columns and point distances (b, n) of bodies ``rows``."""
        body, obj = self.body, self.obj
        posed = dense.pose(body, self.arrays, body.full_pose(state.pose), state.coeffs, state.transl)
        diff = posed.points - self.targets[..., rows]
        w = self.weights[:, rows]
        cost = np.einsum("nb,ncb,ncb->b", w, diff, diff, dtype=np.float64)
        grad = self._columns(dense.gradient(body, self.arrays, posed, diff * w[:, None]))
        x = _flat(state)
        if obj.pose_mean is not None:
            x[:, : body.num_pose] -= obj.pose_mean[rows]
        sub = self._sub(obj, rows)
        grad = grad + self._prior(rows) * x[:, self.cols]
        dist = np.sqrt(np.einsum("ncb,ncb->bn", diff, diff, dtype=np.float64))
        cost = cost + _prior_cost(sub, state)
        if obj.pose_terms is not None:
            cost = cost + obj.pose_terms.add_system(state.pose, self.fitted_pose, grad, None)
        return cost, grad, dist

    def terms_hessian(self, hess: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """(b, P, P) ``hess`` plus the non-quadratic priors' Gauss–Newton matrix at (b, Q) ``pose`` (a new
        array; ``hess`` itself when there are none): their active set changes faster than the data's matrix
        is refreshed."""
        if self.obj.pose_terms is None:
            return hess
        hess = hess.copy()
        self.obj.pose_terms.add_system(pose, self.fitted_pose, None, hess)
        return hess

    @staticmethod
    def _sub(obj: Objective, rows: np.ndarray) -> Objective:
        prior = obj.pose_prior
        if prior is not None and prior.ndim == 2:
            prior = prior[rows]
        mean = None if obj.pose_mean is None else obj.pose_mean[rows]
        return Objective(
            **{**obj.__dict__, "pose_prior": prior, "pose_mean": mean, "pose_terms": None, "temporal": None}
        )

    def hessian(self, state: State, rows: np.ndarray) -> np.ndarray:
        """(b, P, P) Gauss–Newton matrix of the subset (without the pose correctives' share, see
        :mod:`smplcore.fit.normal_matrix`), scaled to the whole set, plus the priors' diagonal."""
        body, hobj = self.body, self.hobj
        posed = dense.pose(body, self.harrays, body.full_pose(state.pose), state.coeffs, state.transl)
        weights = hobj.weights[rows] * self.ratio[rows, None]
        hess = normal_matrix(body, hobj.points, self.harrays, posed, weights, self.select)
        if self.transform is not None:
            hess = self.transform.T @ hess @ self.transform
        np.einsum("bii->bi", hess)[...] += self._prior(rows)
        return hess

    def _columns(self, jac: np.ndarray) -> np.ndarray:
        """The fitted parameters' columns of a Jacobian (or gradient) over [θ, coeffs, transl]."""
        if self.transform is not None:
            return jac @ self.transform
        return jac if self.select is None else jac[..., self.select]

    def _prior(self, rows: np.ndarray) -> np.ndarray:
        """(b, P) weights of the quadratic priors on the fitted columns."""
        body, obj = self.body, self.obj
        q, k = body.num_pose, body.num_coeffs
        full = np.zeros((len(rows), q + k + 3))
        if obj.pose_prior is not None:
            prior = obj.pose_prior
            full[:, :q] = prior[rows] if prior.ndim == 2 and prior.shape[0] == len(obj.weights) else prior
        if obj.shape_prior:
            full[:, q : q + k] = obj.shape_prior
        return full[:, self.cols]


def refine(
    body: FitBody,
    obj: Objective,
    state: State,
    *,
    hessian_obj: Objective | None = None,
    dtype: npt.DTypeLike = np.float64,
    max_iter: int = 30,
    tol: float = 1e-8,
    step_tol: float = 1e-7,
    abs_tol: float | None = None,
    hessian_every: int = 1,
    workers: int | None = 1,
) -> tuple[State, np.ndarray, np.ndarray, np.ndarray, int]:
    """Minimise ``obj`` from ``state`` (see the module docstring; ``hessian_obj`` is the subset objective,
    default ``obj`` itself). Independent chunks of bodies run in up to ``workers`` threads (None: every
    core; one for small problems, see ``_THREAD_MIN_WORK``).

    Returns the state, (B,) costs, (B, n) final point distances, (B,) converged flags (relative cost
    decrease below ``tol``, decrease per unit weight below ``abs_tol`` m², largest step below
    ``step_tol``, or a cost already below ``abs_tol`` per unit weight) and the most iterations run.
    """
    problem = _Problem(body, obj, hessian_obj, dtype)
    if len(obj.points.ids) * len(state.pose) < _THREAD_MIN_WORK:
        workers = 1
    if abs_tol is None:  # what the working precision resolves: ~0.1 µm (float64), ~1 µm (float32) RMS
        abs_tol = 1e-14 if np.dtype(dtype) == np.float64 else 1e-12
    if np.dtype(dtype) != np.float64:
        # float32 points resolve a cost to ~1e-5 relative and a pose to ~1e-6: tighter tests only add
        # rejected steps
        tol, step_tol = max(tol, 1e-5), max(step_tol, 1e-6)
    batch = len(state.pose)
    q = body.num_pose
    cols = problem.cols
    shared_cols = np.zeros(len(cols), bool)
    is_coeff = (cols >= q) & (cols < q + body.num_coeffs)
    shared_cols[is_coeff] = obj.shared[cols[is_coeff] - q]
    temporal = obj.temporal if batch > 1 else None
    coupled = (bool(shared_cols.any()) or temporal is not None) and batch > 1
    if not shared_cols.any() or batch == 1:
        shared_cols[:] = False
    x = _flat(state).copy()
    costs = np.empty(batch)
    dists = np.empty((batch, len(obj.points.ids)))
    converged = np.zeros(batch, bool)
    if coupled:
        parts = [np.arange(batch)]
    else:  # a chunk per thread, each small enough for the working arrays
        size = chunk_bodies(len(obj.points.ids), len(cols))
        parts = [p for c in chunks(batch, workers) for p in np.array_split(c, -(-len(c) // size))]

    def run(rows: np.ndarray) -> int:
        x[rows], costs[rows], dists[rows], converged[rows], its = _solve(
            body,
            problem,
            x[rows],
            rows,
            shared_cols,
            coupled,
            max_iter,
            tol,
            step_tol,
            abs_tol,
            hessian_every,
            workers if coupled else 1,
        )
        return its

    most = max(map_chunks(run, parts, workers), default=0)
    return _unflat(body, x), costs, dists, converged, most


def chunk_bodies(points: int, params: int) -> int:
    """Bodies per chunk for ``points`` target points and ``params`` fitted parameters (see _CHUNK_VALUES)."""
    per_body = max(1, params * (params + 3 * points))
    return max(1, min(_CHUNK_POINTS // max(1, points), _CHUNK_VALUES // per_body))


def _threaded(method: Callable, workers: int | None, size: int | None = None) -> Callable:
    """``method(state, rows)`` over chunks of the bodies in threads (and of at most ``size`` bodies), the
    results joined: coupled bodies are one system for the step but independent for the cost, gradient and
    Gauss-Newton matrix."""

    def call(state: State, rows: np.ndarray) -> Any:
        parts = chunks(len(rows), workers)
        if size is not None:
            parts = [p for c in parts for p in np.array_split(c, -(-len(c) // size))]
        if len(parts) == 1:
            return method(state, rows)
        # each chunk's results are written into the joined arrays as it comes (no list of them, then a copy)
        first = method(state.take(parts[0]), rows[parts[0]])
        as_tuple = isinstance(first, tuple)
        firsts = first if as_tuple else (first,)
        outs = tuple(np.empty((len(rows), *f.shape[1:]), f.dtype) for f in firsts)

        def fill(p: np.ndarray, result: Any = None) -> None:
            result = method(state.take(p), rows[p]) if result is None else result
            for out, part in zip(outs, result if as_tuple else (result,)):
                out[p] = part

        fill(parts[0], first)
        del first, firsts
        map_chunks(fill, parts[1:], workers)
        return outs if as_tuple else outs[0]

    return call


def _solve(body, problem, x, rows, shared_cols, coupled, max_iter, tol, step_tol, abs_tol, every, workers=1):
    """LM on the bodies ``rows`` (x: their (b, Q + K + 3) parameters); ``workers`` threads share the
    per-body work of coupled bodies."""
    cols = problem.cols
    size = chunk_bodies(len(problem.obj.points.ids), len(cols)) if coupled else None
    evaluate, hessian = _threaded(problem.evaluate, workers, size), _threaded(problem.hessian, workers, size)
    temporal = problem.obj.temporal if coupled else None
    if temporal is not None:  # the sequence's term on top of each body's (the bodies are all of the sequence)
        coupling = np.zeros(len(cols))
        where = {int(c): i for i, c in enumerate(temporal.cols)}
        for i, c in enumerate(cols):
            if int(c) in where and not shared_cols[i]:
                coupling[i] = temporal.weights[where[int(c)]]
        per_body = evaluate

        def evaluate(state: State, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            cost, grad, dist = per_body(state, rows)
            extra, g = temporal.cost_gradient(_flat(state))
            return cost + extra, grad + g[:, cols], dist

    scale = np.maximum(problem.obj.weights[rows].sum(1), 1e-300)
    cost, grad, dist = evaluate(_unflat(body, x), rows)
    converged = cost <= abs_tol * scale
    everyone = np.arange(len(rows))
    damping = np.full(len(rows), 1e-4)
    hess: np.ndarray | None = None
    fresh = np.zeros(len(rows), bool)  # the Gauss-Newton matrix was computed at the current state
    age = np.zeros(len(rows), np.int64)
    iterations = 0
    for _ in range(max_iter):
        if converged.all():
            break
        # coupled bodies are one system: all of them step until every one has converged
        active = everyone if coupled else np.flatnonzero(~converged)
        iterations += 1
        sub = rows[active]
        stale = active[~fresh[active] & ((age[active] >= every) | (iterations == 1))]
        if len(stale) == len(rows):  # every body: no copy
            hess = hessian(_unflat(body, x), rows)
        elif len(stale):
            part = hessian(_unflat(body, x[stale]), rows[stale])
            if hess is None:  # bodies already at their optimum at the start never need theirs
                hess = np.zeros((len(rows), *part.shape[1:]))
            hess[stale] = part
        fresh[stale], age[stale] = True, 0
        assert hess is not None
        all_active = len(active) == len(rows)
        system = problem.terms_hessian(hess if all_active else hess[active], x[active, : body.num_pose])
        if temporal is not None:
            step = temporal_step(system, grad[active], damping[active], shared_cols, coupling)
        else:
            step = _step(system, grad[active], damping[active], shared_cols)
        trial = x[active].copy()
        trial[:, cols] += step
        new_cost, new_grad, new_dist = evaluate(_unflat(body, trial), sub)
        better = np.full(len(active), new_cost.sum() <= cost[active].sum()) if coupled else new_cost <= cost[active]
        old = cost[active]
        decrease = (old - new_cost) / np.maximum(old, 1e-300)
        tiny = (old - new_cost) < abs_tol * scale[active]
        small = np.max(np.abs(step), axis=1) < step_tol
        keep = active[better]
        x[keep], cost[keep], grad[keep], dist[keep] = (
            trial[better],
            new_cost[better],
            new_grad[better],
            new_dist[better],
        )
        fresh[keep] = False
        age[active] += 1
        # a rejected step, or one that moved far (the linearisation has changed): a new matrix next time
        age[active[~better | (np.max(np.abs(step), axis=1) > _FAR)]] = every
        damping[active] = np.where(better, np.maximum(damping[active] / 3, 1e-9), damping[active] * 10)
        done = (better & ((decrease < tol) | small | tiny)) | (~better & (damping[active] > 1e8))
        done |= cost[active] <= abs_tol * scale[active]  # at the precision's floor: steps only add noise
        if coupled:  # each body's own test at the system's last accepted step (a mean decrease hides a body)
            converged[:] = np.where(better, done, converged | done)
        else:
            converged[active] |= done
    return x, cost, dist, converged, iterations
