"""Levenberg–Marquardt over bodies: pose parameters, shape coefficients and translation.

The residuals are weighted point differences (posed model points minus targets) plus optional
quadratic priors; the Jacobian is :func:`smplcore.fit.body.pose_points`' exact one, mapped to the
model's own pose parameters (axis-angle blocks or hand PCA coefficients). Bodies are independent
(each with its own damping), except that shape coefficients can be shared over the batch, which
couples them through a Schur complement.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.fit.body import FitBody, Points, pose_points

# Bodies per Jacobian chunk: keep a chunk's Jacobian (chunk × 3 n × P doubles) near 64 MB.
_CHUNK_VALUES = 8_000_000
# Up to this many residual rows per body, normal equations are formed by batched einsum.
_SMALL_ROWS = 600


@dataclass
class State:
    """Parameters of B bodies: pose (B, Q), shape and expression coefficients (B, K), translation (B, 3)."""

    pose: np.ndarray
    coeffs: np.ndarray
    transl: np.ndarray

    def copy(self) -> State:
        return State(self.pose.copy(), self.coeffs.copy(), self.transl.copy())

    def take(self, rows: np.ndarray) -> State:
        """The bodies ``rows`` (a copy)."""
        return State(self.pose[rows], self.coeffs[rows], self.transl[rows])

    def put(self, rows: np.ndarray, part: State) -> None:
        """Set the bodies ``rows`` to ``part``'s."""
        self.pose[rows], self.coeffs[rows], self.transl[rows] = part.pose, part.coeffs, part.transl


@dataclass
class Objective:
    """What is minimised: Σ_i w_i |x_i − y_i|² (+ Σ residuals of ``extra``) + priors.

    Attributes
    ----------
    points : the model points compared.
    targets : (B, n, 3) their targets.
    weights : (B, n) non-negative weights.
    free_coeffs : (K,) which shape/expression coefficients are fitted.
    shared : (K,) which fitted coefficients are shared by the whole batch.
    fit_transl : fit the translation.
    shape_prior : weight of Σ c_k² over the fitted coefficients.
    pose_prior : (Q,), (B, 1) or (B, Q) weights of Σ (q_k − μ_k)² (None: none).
    pose_mean : (B, Q) the centre μ of the pose prior (None: zero).
    pose_terms : the non-quadratic pose priors (limits, hinge, mixture), a
        :class:`~smplcore.fit.prior_terms.PoseTerms`, or None.
    temporal : smoothness over consecutive bodies, a :class:`~smplcore.fit.temporal.Temporal`, or None
        (:func:`smplcore.fit.gauss_newton.refine` solves the coupled system).
    """

    points: Points
    targets: np.ndarray
    weights: np.ndarray
    free_coeffs: np.ndarray
    shared: np.ndarray
    fit_transl: bool = True
    shape_prior: float = 0.0
    pose_prior: np.ndarray | None = None
    pose_mean: np.ndarray | None = None  # (B, Q) the pose prior's centre (None: zero)
    pose_terms: Any = None  # PoseTerms or None
    temporal: Any = None  # Temporal or None: couples consecutive bodies


def _columns(body: FitBody, obj: Objective) -> np.ndarray:
    """Indices into [pose Q, coeffs K, transl 3] of the fitted parameters."""
    q, k = body.num_pose, body.num_coeffs
    cols = [np.arange(q), q + np.flatnonzero(obj.free_coeffs)]
    if obj.fit_transl:
        cols.append(q + k + np.arange(3))
    return np.concatenate(cols)


def _flat(state: State) -> np.ndarray:
    return np.concatenate([state.pose, state.coeffs, state.transl], axis=1)


def _unflat(body: FitBody, x: np.ndarray) -> State:
    q, k = body.num_pose, body.num_coeffs
    return State(x[:, :q], x[:, q : q + k], x[:, q + k :])


def residual_cost(body: FitBody, obj: Objective, state: State) -> np.ndarray:
    """(B,) objective value of each body (shared-coefficient priors counted once per body)."""
    posed = pose_points(body, obj.points, body.full_pose(state.pose), state.coeffs, state.transl).points
    diff = posed - obj.targets
    cost = np.einsum("bn,bnc,bnc->b", obj.weights, diff, diff)
    return cost + _prior_cost(obj, state)


def _prior_cost(obj: Objective, state: State) -> np.ndarray:
    cost = np.zeros(len(state.pose))
    if obj.shape_prior:
        c = state.coeffs[:, obj.free_coeffs]
        cost = cost + obj.shape_prior * np.sum(c * c, axis=1)
    if obj.pose_prior is not None:
        d = state.pose if obj.pose_mean is None else state.pose - obj.pose_mean
        cost = cost + np.sum(obj.pose_prior * d * d, axis=1)
    if obj.pose_terms is not None:
        cost = cost + obj.pose_terms.cost(state.pose)
    return cost


def _column_map(body: FitBody, cols: np.ndarray) -> np.ndarray:
    """(3 J + K + 3, P) map from the Jacobian's columns [θ, coeffs, transl] to the fitted parameters."""
    nj3, q = 3 * body.num_joints, body.num_pose
    full = np.zeros((nj3 + body.num_coeffs + 3, q + body.num_coeffs + 3))
    full[:nj3, :q] = np.eye(nj3) if body.pose_map is None else body.pose_map.T
    full[nj3:, q:] = np.eye(body.num_coeffs + 3)
    return full[:, cols]


def normal_equations(
    body: FitBody, obj: Objective, state: State, *, hessian: bool = True
) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """Gauss–Newton system of each body: H (B, P, P) (None without ``hessian``), g (B, P) over the fitted
    columns, and cost (B,)."""
    batch = len(state.pose)
    cols = _columns(body, obj)
    n = len(obj.points.ids)
    width = 3 * body.num_joints + body.num_coeffs + 3
    chunk = max(1, _CHUNK_VALUES // (3 * n * width))
    hess = np.empty((batch, len(cols), len(cols)))
    grad = np.empty((batch, len(cols)))
    cost = np.empty(batch)
    theta = body.full_pose(state.pose)
    transform = _column_map(body, cols)
    for s in range(0, batch, chunk):
        e = min(batch, s + chunk)
        lin = pose_points(body, obj.points, theta[s:e], state.coeffs[s:e], state.transl[s:e], jacobian=True)
        assert lin.jacobian is not None  # asked for
        jac = lin.jacobian.reshape(e - s, 3 * n, width)
        sw = np.sqrt(np.repeat(obj.weights[s:e], 3, axis=1))
        res = (lin.points - obj.targets[s:e]).reshape(e - s, 3 * n) * sw
        if 3 * n <= _SMALL_ROWS:  # tiny systems: batched C loops (per-body BLAS calls cost more than they do)
            jac = jac @ transform
            grad[s:e] = np.einsum("brp,br->bp", jac, res * sw)
            if hessian:
                jw = jac * sw[..., None]
                hess[s:e] = np.einsum("brp,brq->bpq", jw, jw)
            cost[s:e] = np.einsum("br,br->b", res, res)
            continue
        for b in range(e - s):
            if hessian:
                jb = jac[b] * sw[b, :, None]
                hess[s + b] = transform.T @ (jb.T @ jb) @ transform
                grad[s + b] = transform.T @ (jb.T @ res[b])
            else:
                grad[s + b] = transform.T @ (jac[b].T @ (res[b] * sw[b]))
            cost[s + b] = res[b] @ res[b]
    # priors
    q_ = body.num_pose
    x = _flat(state)
    if obj.pose_mean is not None:
        x[:, : body.num_pose] -= obj.pose_mean
    x = x[:, cols]
    prior = _prior_diagonal(obj, cols, body.num_pose, body.num_coeffs, batch)
    grad = grad + prior * x
    cost = cost + _prior_cost(obj, state)
    system = hess + prior[:, :, None] * np.eye(len(cols)) if hessian else None
    if obj.pose_terms is not None:
        obj.pose_terms.add_system(state.pose, np.where(cols < q_, cols, -1), grad, system)
    return system, grad, cost


def _step(hess: np.ndarray, grad: np.ndarray, damping: np.ndarray, shared_cols: np.ndarray) -> np.ndarray:
    """Damped Gauss–Newton step of each body; columns ``shared_cols`` get one value for the whole batch.
    ``hess`` is damped in place for the solve and restored (a copy of a (B, P, P) stack costs as much as
    the solve)."""
    diag = np.einsum("bii->bi", hess)
    saved = diag.copy()
    diag += damping[:, None] * (saved + 1e-9)
    try:
        return _damped_step(hess, grad, shared_cols)
    finally:
        diag[...] = saved


# Bodies per block of the step's solves: the copies of their (b, P, P) matrices stay near 16 MB.
_STEP_VALUES = 2_000_000


def _damped_step(damped: np.ndarray, grad: np.ndarray, shared_cols: np.ndarray) -> np.ndarray:
    batch, size = len(grad), max(1, _STEP_VALUES // max(1, damped.shape[-1] ** 2))
    if not shared_cols.any():
        out = np.empty_like(grad)
        for a in range(0, batch, size):
            out[a : a + size] = -np.linalg.solve(damped[a : a + size], grad[a : a + size, :, None])[..., 0]
        return out
    s, p = np.flatnonzero(shared_cols), np.flatnonzero(~shared_cols)
    hinv_hps, hinv_gp = np.empty((batch, len(p), len(s))), np.empty((batch, len(p)))
    schur, rhs = np.zeros((len(s), len(s))), np.zeros(len(s))
    for a in range(0, batch, size):  # the Schur complement of the shared columns, block by block of bodies
        d, g = damped[a : a + size], grad[a : a + size]
        hpp, hps, hss = d[:, p[:, None], p], d[:, p[:, None], s], d[:, s[:, None], s]
        gp, gs = g[:, p], g[:, s]
        sol = np.linalg.solve(hpp, np.concatenate([hps, gp[..., None]], axis=-1))  # Hpp⁻¹ [Hps, gp]
        hinv_hps[a : a + size], hinv_gp[a : a + size] = sol[..., :-1], sol[..., -1]
        schur += np.sum(hss - np.swapaxes(hps, 1, 2) @ sol[..., :-1], axis=0)
        rhs += np.sum(gs - np.einsum("bps,bp->bs", hps, sol[..., -1]), axis=0)
    ds = -np.linalg.solve(schur, rhs)
    dp = -(hinv_gp + hinv_hps @ ds)
    step = np.empty_like(grad)
    step[:, p], step[:, s] = dp, ds
    return step


def _prior_diagonal(obj: Objective, cols: np.ndarray, q: int, k: int, batch: int) -> np.ndarray:
    """(B, P) weights of the quadratic priors on the fitted columns."""
    prior = np.zeros((batch, len(cols)))
    if obj.pose_prior is not None:
        prior[:, :q] = obj.pose_prior
    if obj.shape_prior:
        prior[:, (cols >= q) & (cols < q + k)] = obj.shape_prior
    return prior


def _rescaled(hess: np.ndarray, ratio: np.ndarray, obj: Objective, cols: np.ndarray, q: int, k: int) -> np.ndarray:
    """A subset's Gauss–Newton matrix scaled to the whole set (the priors' diagonal is not scaled)."""
    eye = _prior_diagonal(obj, cols, q, k, len(hess))[:, :, None] * np.eye(len(cols))
    return (hess - eye) * ratio[:, None, None] + eye


def levenberg_marquardt(
    body: FitBody,
    obj: Objective,
    state: State,
    *,
    max_iter: int = 30,
    tol: float = 1e-8,
    step_tol: float = 1e-7,
    abs_tol: float = 1e-14,
    hessian_obj: Objective | None = None,
) -> tuple[State, np.ndarray, np.ndarray, int]:
    """Minimise ``obj`` from ``state``.

    With ``hessian_obj`` (the same objective on a subset of the points), the Gauss–Newton matrix comes
    from it, scaled by the ratio of the total weights, while the gradient and the cost come from ``obj``:
    each iteration then costs a gradient over all points, and the fixed point is still ``obj``'s optimum.

    Returns the state, (B,) final costs, (B,) converged flags (the relative decrease of the cost fell
    below ``tol`` or its decrease per unit weight below ``abs_tol`` (m²), or the largest step fell below
    ``step_tol`` (radians, metres)) and the
    number of iterations run.
    """
    batch = len(state.pose)
    cols = _columns(body, obj)
    q = body.num_pose
    shared_cols = np.zeros(len(cols), bool)
    coeff_pos = cols - q
    is_coeff = (cols >= q) & (cols < q + body.num_coeffs)
    shared_cols[is_coeff] = obj.shared[coeff_pos[is_coeff]]
    coupled = bool(shared_cols.any()) and batch > 1
    if not coupled:
        shared_cols[:] = False
    damping = np.full(batch, 1e-4)
    converged = np.zeros(batch, bool)
    scale = np.maximum(obj.weights.sum(1), 1e-300)
    cost: np.ndarray | None = None
    iterations = 0
    for _ in range(max_iter):
        iterations += 1
        if hessian_obj is None:
            hess, grad, cost = normal_equations(body, obj, state)
        else:
            _, grad, cost = normal_equations(body, obj, state, hessian=False)
            hess, _, _ = normal_equations(body, hessian_obj, state)
            ratio = obj.weights.sum(1) / np.maximum(hessian_obj.weights.sum(1), 1e-300)
            assert hess is not None  # asked for
            hess = _rescaled(hess, ratio, obj, cols, q, body.num_coeffs)
        assert hess is not None  # asked for
        active = ~converged
        for _ in range(8):  # raise the damping where a step does not decrease the cost
            step = _step(hess, grad, damping, shared_cols)
            x = _flat(state)
            trial = x.copy()
            trial[:, cols] += np.where(active[:, None], step, 0.0)
            trial_state = _unflat(body, trial)
            new_cost = residual_cost(body, obj, trial_state)
            if coupled:
                better = np.full(batch, new_cost.sum() <= cost.sum())
            else:
                better = new_cost <= cost
            better &= active
            if better.any() or not active.any():
                break
            damping = np.where(active, damping * 10, damping)
        decrease = (cost - new_cost) / np.maximum(cost, 1e-300)
        small_step = np.max(np.abs(step), axis=1) < step_tol
        tiny = (cost - new_cost) < abs_tol * scale  # the RMS error moves by less than ~sqrt(abs_tol) metres
        x[better] = trial[better]
        state = _unflat(body, x)
        cost = np.where(better, new_cost, cost)
        damping = np.where(better, np.maximum(damping / 3, 1e-9), damping * 10)
        done = (better & ((decrease < tol) | small_step | tiny)) | (~better & (damping > 1e8))
        if coupled:
            done = np.full(batch, done.all() or (better.all() and decrease.sum() < tol * batch))
        converged |= done & active
        if converged.all():
            break
    if cost is None:  # no iteration ran (max_iter=0): the cost of the start
        cost = residual_cost(body, obj, state)
    return state, cost, converged, iterations
