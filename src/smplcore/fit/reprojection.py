"""The 2D keypoint objective and its Levenberg–Marquardt solver.

Keypoints are linear combinations of the fitting points of :class:`~smplcore.fit.body.FitBody`
(skeleton joints, vertex joints, midpoints, regressor rows), projected by a pinhole
:class:`~smplcore.fit.camera.Camera`. The data term is SMPLify's robust Geman–McClure reprojection
cost ``Σ_k c_k ρ(|π(x_k) − y_k|²)``, ``ρ(e²) = σ² e² / (σ² + e²)``, scaled by ``(z / f)²`` (pixels at
the body's depth become metres, so the priors' weights do not depend on the image size). It is
minimised by Gauss–Newton with iteratively reweighted residuals (weights ``c ρ'(e²)``, a majoriser of
the robust cost) and Levenberg damping, on the exact Jacobian of the model's points. The priors of
:mod:`smplcore.fit.priors` (and VPoser's encoder mean, :mod:`smplcore.fit.vposer`) enter as residuals.

**Upright prior.** 2D keypoints barely tell whether a body leans towards or away from the camera, and
nothing at all when the hips and legs are out of the image (a body lying along the line of sight then
fits an upper-body photo as well as a standing one). A prior keeps the body from leaning along the line
of sight: with ``d`` the vector from the pelvis to the neck (and, scaled to the same length, from the
pelvis to ``spine1``, which follows the pelvis alone), the residual is ``d · h`` (metres), ``h`` the
camera's viewing direction made horizontal (perpendicular to the world's up). A lean across the image,
which the keypoints show, is left to them.

With ``Terms.estimate_focal`` the flat parameters carry one more column, ``s = log(f / f₀)`` (``f₀`` the
camera's focal length, both f_x and f_y scaled alike), shared by the batch; a weak prior ``w s²``
(counted once for the batch) pulls it towards the camera's focal length. Focal length and depth are
nearly interchangeable (a body twice as far seen with twice the focal length looks almost the same), so
the translation columns hold ``T̃`` with the body's position in camera coordinates scaled along:
``R T + t = e^s (R T̃ + t)``. Moving ``s`` alone then keeps each body's place and size in the image
and changes only its perspective, which is what the data can tell; :func:`focal_translation` maps
``T̃`` back to ``T``. Bodies are independent (each with its own damping)
unless shape is shared or a temporal smoothness couples consecutive bodies; then one sparse system is
solved for the whole batch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smplcore.fit.body import FitBody, Points, pose_points
from smplcore.fit.camera import Camera
from smplcore.fit.priors import GMMPrior, bending_residuals, limit_residuals
from smplcore.fit.solver import State
from smplcore.fit.vposer import POSE_WIDTH, VPoserPrior


@dataclass(frozen=True)
class KeypointMap:
    """K keypoints as combinations (K, n) of the fitting points ``points``; ``available`` (K,).

    ``guide`` (G, n): the body's own points the upright prior reads (pelvis, spine1, neck; G = 0 when the
    model lacks them), posed with the keypoints at no extra cost.
    """

    points: Points
    combo: np.ndarray
    available: np.ndarray
    names: tuple[str, ...]
    guide: np.ndarray | None = None


@dataclass
class Terms:
    """What is minimised for a batch of B bodies (see the module docstring).

    ``free`` (P,) marks the fitted columns of the flat parameters [pose Q, coeffs K, transl 3];
    ``shared`` (P,) those shared by the batch; ``body_cols`` the columns of ``body_pose`` (D,) with
    bounds ``lo``, ``hi`` (D,); ``bend`` (index into body_cols, sign) pairs; ``smooth`` the weight of
    Σ_t |x_t − x_{t−1}|² over pose and translation columns. ``vposer`` the VPoser prior on the first 63
    body-pose values (weight ``vposer_prior``); ``estimate_focal``: the flat parameters end with the
    shared ``log(f / f₀)`` column, with the prior weight ``focal_prior``.
    """

    kmap: KeypointMap
    camera: Camera
    targets: np.ndarray  # (B, K, 2) pixels
    weights: np.ndarray  # (B, K) confidences (0: unused)
    scale: np.ndarray  # (B,) metres per pixel at the body
    sigma: float
    free: np.ndarray
    shared: np.ndarray
    beta_cols: np.ndarray
    body_cols: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    bend_index: np.ndarray
    bend_sign: np.ndarray
    shape_prior: float = 0.0
    pose_prior: float = 0.0
    limit_prior: float = 0.0
    bend_prior: float = 0.0
    gmm: GMMPrior | None = None
    gmm_prior: float = 0.0
    smooth: float = 0.0
    smooth_cols: np.ndarray | None = None
    vposer: VPoserPrior | None = None
    vposer_prior: float = 0.0
    estimate_focal: bool = False
    focal_prior: float = 0.0
    focal_centre: float = 0.0  # the prior's centre, log(f₀ / camera.focal)
    upright: float | np.ndarray = 0.0  # weight of the upright prior (m² per m²), or (B,) one per body
    up: np.ndarray | None = None  # (3,) the world's up direction


def flat(state: State) -> np.ndarray:
    return np.concatenate([state.pose, state.coeffs, state.transl], axis=1)


def unflat(body: FitBody, x: np.ndarray) -> State:
    q, k = body.num_pose, body.num_coeffs
    return State(x[:, :q].copy(), x[:, q : q + k].copy(), x[:, q + k : q + k + 3].copy())


def keypoints_3d(body: FitBody, kmap: KeypointMap, state: State, jacobian: bool = False):
    """(B, K, 3) keypoints of the bodies and, with ``jacobian``, (B, K, 3, P) over the flat parameters."""
    pts, jac, _, _ = posed(body, kmap, state, jacobian)
    return pts, jac


def posed(body: FitBody, kmap: KeypointMap, state: State, jacobian: bool = False):
    """The keypoints (B, K, 3) and the guide points (B, G, 3) of the bodies and, with ``jacobian``, their
    Jacobians (B, K, 3, P) and (B, G, 3, P) over the flat parameters (else None)."""
    lin = pose_points(body, kmap.points, body.full_pose(state.pose), state.coeffs, state.transl, jacobian)
    guide = np.zeros((0, kmap.combo.shape[1])) if kmap.guide is None else kmap.guide
    pts, gpts = kmap.combo @ lin.points, guide @ lin.points
    if not jacobian:
        return pts, None, gpts, None
    nj3 = 3 * body.num_joints
    jac = lin.jacobian
    assert jac is not None  # pose_points was asked for it
    if body.pose_map is not None:
        jac = np.concatenate([jac[..., :nj3] @ body.pose_map.T, jac[..., nj3:]], axis=-1)
    batch, n, _, width = jac.shape
    flat_jac = jac.reshape(batch, n, 3 * width)
    return (
        pts,
        (kmap.combo @ flat_jac).reshape(batch, -1, 3, width),
        gpts,
        (guide @ flat_jac).reshape(batch, -1, 3, width),
    )


def upright_residuals(guides: np.ndarray, guide_jac: np.ndarray | None, up: np.ndarray, toward: np.ndarray):
    """The upright prior's residuals (B, G − 1): how far (metres) the vectors ``d`` from the first guide
    point (the pelvis) to the others lean along ``toward`` (the camera's horizontal line of sight, (3,),
    perpendicular to the world's ``up``), each scaled to the length of the last (pelvis to neck); and
    their Jacobians (B, G − 1, P) (None without ``guide_jac``)."""
    d = guides[:, 1:] - guides[:, :1]  # (B, G-1, 3)
    length = np.maximum(np.linalg.norm(d, axis=-1), 1e-9)
    scale = length[:, -1:] / length  # every vector as long as pelvis → neck (scale held constant)
    res = scale * (d @ toward)
    if guide_jac is None:
        return res, None
    dd = guide_jac[:, 1:] - guide_jac[:, :1]  # (B, G-1, 3, P)
    return res, scale[..., None] * np.einsum("c,bgcp->bgp", toward, dd)


def reprojection(body: FitBody, terms: Terms, state: State) -> np.ndarray:
    """(B, K) pixel distances of the projected keypoints (by ``terms.camera``) from their targets."""
    pts, _ = keypoints_3d(body, terms.kmap, state)
    return np.linalg.norm(terms.camera.project(pts) - terms.targets, axis=-1)


def _prior_parts(terms: Terms, x: np.ndarray, guides: np.ndarray | None = None, guide_jac: np.ndarray | None = None):
    """Residual blocks of the priors: a list of (weight, residual (B, m), Jacobian (B, m, P) or
    diagonal (B, m) on columns ``cols``), plus the GMM's constant cost (B,). ``guides`` (B, G, 3) and
    ``guide_jac`` (B, G, 3, P) are the posed guide points, for the upright prior."""
    parts = []
    const = np.zeros(len(x))
    upright = np.broadcast_to(np.asarray(terms.upright, np.float64), (len(x),))
    if upright.any() and terms.up is not None and guides is not None and guides.shape[1] > 1:
        res, jac = upright_residuals(guides, guide_jac, terms.up, _line_of_sight(terms.camera, terms.up))
        root = np.sqrt(upright)[:, None]  # per-body weights, into the residuals
        width = guide_jac.shape[-1] if guide_jac is not None else x.shape[1]
        cols = np.arange(min(width, x.shape[1]))
        jac = np.zeros((len(x), res.shape[1], len(cols))) if jac is None else jac[..., cols] * root[..., None]
        parts.append((1.0, res * root, jac, cols))
    if terms.shape_prior and len(terms.beta_cols):
        parts.append(
            (terms.shape_prior, x[:, terms.beta_cols], np.ones((len(x), len(terms.beta_cols))), terms.beta_cols)
        )
    theta = x[:, terms.body_cols]
    ones = np.ones_like(theta)
    if terms.pose_prior:
        parts.append((terms.pose_prior, theta, ones, terms.body_cols))
    if terms.limit_prior:
        res, diag = limit_residuals(theta, terms.lo, terms.hi)
        parts.append((terms.limit_prior, res, diag, terms.body_cols))
    if terms.bend_prior and len(terms.bend_index):
        res, diag = bending_residuals(theta, terms.bend_index, terms.bend_sign)
        parts.append((terms.bend_prior, res, diag, terms.body_cols[terms.bend_index]))
    if terms.gmm is not None and terms.gmm_prior:
        best, res, jac = terms.gmm.residuals(theta)
        parts.append((terms.gmm_prior, res, jac, terms.body_cols))
        const = 2 * terms.gmm_prior * terms.gmm.penalty[best]
    if terms.vposer is not None and terms.vposer_prior:
        cols = terms.body_cols[:POSE_WIDTH]
        res, jac = terms.vposer.residuals(x[:, cols])
        parts.append((terms.vposer_prior, res, jac, cols))
    if terms.estimate_focal and terms.focal_prior:
        # one camera for the batch: each body carries 1/B of the prior
        res = x[:, -1:] - terms.focal_centre
        parts.append((terms.focal_prior / len(x), res, np.ones_like(res), np.array([x.shape[1] - 1])))
    return parts, const


def _line_of_sight(camera: Camera, up: np.ndarray) -> np.ndarray:
    """(3,) the camera's viewing direction made horizontal (perpendicular to ``up``), unit length; the
    camera's y axis made horizontal when the camera looks straight up or down."""
    for axis in (2, 1):
        view = camera.rotation[axis]  # the camera's axis in the world
        flat = view - (view @ up) * up
        if np.linalg.norm(flat) > 1e-6:
            return flat / np.linalg.norm(flat)
    return np.array([1.0, 0.0, 0.0])


def smooth_cost(terms: Terms, x: np.ndarray) -> np.ndarray:
    """(B,) temporal smoothness cost, each difference charged to the later body."""
    cost = np.zeros(len(x))
    if terms.smooth and len(x) > 1:
        d = np.diff(x[:, terms.smooth_cols], axis=0)
        cost[1:] = terms.smooth * np.sum(d * d, axis=1)
    return cost


def focal_translation(body: FitBody, camera: Camera, x: np.ndarray) -> np.ndarray:
    """(B, 3) translations ``T`` of flat parameters (B, P + 1) that end with ``s = log(f/f₀)`` and hold
    ``T̃``: ``R T + t = e^s (R T̃ + t)``."""
    q, k = body.num_pose, body.num_coeffs
    grow = np.exp(x[:, -1:])
    return (
        (x[:, q + k : q + k + 3] @ camera.rotation.T + camera.translation) * grow - camera.translation
    ) @ camera.rotation


def evaluate(body: FitBody, terms: Terms, x: np.ndarray, system: bool = True):
    """Cost (B,) at flat parameters ``x`` (B, P) and, with ``system``, the Gauss–Newton matrices
    H (B, F, F) and gradients g (B, F) over the free columns F (smoothness excluded)."""
    state = unflat(body, x)
    if terms.estimate_focal:
        state.transl = focal_translation(body, terms.camera, x)
    pts, jac, guides, guide_jac = posed(body, terms.kmap, state, system)
    s2 = (terms.scale**2)[:, None]
    uv, d_uv = terms.camera.project_jacobian(pts)
    if terms.estimate_focal:  # u = c + e^s (u₀ − c)
        grow = np.exp(x[:, -1])[:, None, None]
        uv = terms.camera.center + grow * (uv - terms.camera.center)
        d_uv = grow[..., None] * d_uv
        if jac is not None:  # dT/dT̃ = e^s I, dT/ds = Rᵀ (R T + t): the translation's columns
            tc = body.num_pose + body.num_coeffs + np.arange(3)
            d_ts = (state.transl @ terms.camera.rotation.T + terms.camera.translation) @ terms.camera.rotation
            jac_s = jac[..., tc] @ d_ts[:, None, :, None]  # (B, K, 3, 1)
            jac = np.concatenate([jac, jac_s], axis=-1)
            jac[..., tc] *= grow[..., None]
    e = uv - terms.targets
    e2 = np.sum(e * e, axis=-1)
    sig2 = terms.sigma**2
    cost = np.sum(terms.weights * sig2 * e2 / (sig2 + e2) * s2, axis=1)
    parts, const = _prior_parts(terms, x, guides, guide_jac)
    for weight, res, _, _ in parts:
        cost = cost + weight * np.sum(res * res, axis=1)
    cost = cost + const + smooth_cost(terms, x)
    if not system:
        return cost, None, None
    cols = np.flatnonzero(terms.free)
    irls = terms.weights * sig2 * sig2 / (sig2 + e2) ** 2 * s2  # (B, K)
    assert jac is not None  # asked for with system
    j2 = d_uv @ jac[..., cols]  # (B, K, 2, F)
    if terms.estimate_focal and terms.free[-1]:  # the focal's own effect on the pixels: ∂u/∂s = u − c
        j2[..., -1] += uv - terms.camera.center
    jw = j2 * np.sqrt(irls)[:, :, None, None]
    batch, num_k = e.shape[:2]
    jw = jw.reshape(batch, 2 * num_k, len(cols))
    rw = (e * np.sqrt(irls)[..., None]).reshape(batch, 2 * num_k)
    jt = np.swapaxes(jw, 1, 2)
    hess = jt @ jw
    grad = (jt @ rw[..., None])[..., 0]
    where = np.full(x.shape[1], -1)
    where[cols] = np.arange(len(cols))
    for weight, res, pj, pcols in parts:
        idx = where[pcols]
        keep = idx >= 0
        if not keep.any():
            continue
        idx = idx[keep]
        if pj.ndim == 2:  # diagonal Jacobian
            d = pj[:, keep]
            hess[:, idx, idx] += weight * d * d
            grad[:, idx] += weight * d * res[:, keep]
        else:
            m = pj[:, :, keep]
            mt = np.swapaxes(m, 1, 2)
            hess[np.ix_(np.arange(batch), idx, idx)] += weight * (mt @ m)
            grad[:, idx] += weight * (mt @ res[..., None])[..., 0]
    return cost, hess, grad


DAMPING_FLOOR = 0.1


def _damped(hess: np.ndarray, damping: np.ndarray) -> np.ndarray:
    diag = np.diagonal(hess, axis1=-2, axis2=-1)
    # Marquardt's scaling, floored at a fraction of the mean curvature: directions only the priors see
    # (twists) would otherwise take huge steps
    floor = DAMPING_FLOOR * np.maximum(diag.mean(axis=-1, keepdims=True), 1e-12)
    return hess + (damping[..., None] * np.maximum(diag, floor))[..., None] * np.eye(hess.shape[-1])


def _coupled_step(terms: Terms, x: np.ndarray, hess: np.ndarray, grad: np.ndarray, damping: float) -> np.ndarray:
    """One damped step of the whole batch (shared columns and smoothness couple the bodies)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    batch = len(x)
    cols = np.flatnonzero(terms.free)
    shared = terms.shared[cols]
    local = np.flatnonzero(~shared)
    index = np.empty((batch, len(cols)), np.int64)
    index[:, local] = np.arange(batch)[:, None] * len(local) + np.arange(len(local))
    index[:, shared] = batch * len(local) + np.arange(int(shared.sum()))
    size = batch * len(local) + int(shared.sum())
    h = hess.copy()
    g = grad.copy()
    rows = [np.repeat(index[:, :, None], len(cols), 2).ravel()]
    colsi = [np.repeat(index[:, None, :], len(cols), 1).ravel()]
    data = [h.ravel()]
    if terms.smooth and batch > 1:
        where = np.full(x.shape[1], -1)
        where[cols] = np.arange(len(cols))
        sc = where[terms.smooth_cols]
        sc = sc[sc >= 0]
        d = terms.smooth * np.diff(x[:, cols[sc]], axis=0)  # (B-1, S)
        g[1:, sc] += d
        g[:-1, sc] -= d
        a, b = index[1:, sc].ravel(), index[:-1, sc].ravel()
        s = np.full(a.shape, terms.smooth)
        rows += [a, b, a, b]
        colsi += [a, b, b, a]
        data += [s, s, -s, -s]
    mat = sp.coo_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(colsi))), (size, size)).tocsc()
    diag = mat.diagonal()
    mat = mat + sp.diags(damping * diag + 1e-9 * max(diag.max(), 1e-12))
    rhs = np.zeros(size)
    np.add.at(rhs, index.ravel(), g.ravel())
    sol = -spsolve(mat, rhs)
    return sol[index]


def levenberg_marquardt(
    body: FitBody, terms: Terms, state: State, *, max_iter: int = 20, tol: float = 1e-6, step_tol: float = 1e-6
) -> tuple[State, np.ndarray, np.ndarray, int]:
    """Minimise ``terms`` over the free columns from ``state`` (Levenberg–Marquardt with Nielsen's
    damping update from the ratio of the actual to the predicted decrease).

    Returns the state, (B,) costs, (B,) converged flags (relative cost decrease below ``tol`` or a step
    below ``step_tol``) and the iterations run.
    """
    x, cost, converged, iterations = solve_flat(body, terms, flat(state), max_iter=max_iter, tol=tol, step_tol=step_tol)
    return unflat(body, x), cost, converged, iterations


def solve_flat(
    body: FitBody, terms: Terms, x: np.ndarray, *, max_iter: int = 20, tol: float = 1e-6, step_tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """:func:`levenberg_marquardt` on flat parameters (B, P), or (B, P + 1) with ``terms.estimate_focal``."""
    x = np.array(x, dtype=np.float64)
    batch = len(x)
    cols = np.flatnonzero(terms.free)
    coupled = batch > 1 and (bool(terms.shared[cols].any()) or bool(terms.smooth))
    damping = np.full(batch, 1e-2)
    growth = np.full(batch, 2.0)
    converged = np.zeros(batch, bool)
    cost, hess, grad = evaluate(body, terms, x)
    iterations = 0
    while iterations < max_iter:
        iterations += 1
        active = ~converged
        if coupled:
            # (the predicted decrease below leaves out the smoothness terms: it only steers the damping)
            step = _coupled_step(terms, x, hess, grad, float(damping[0]))
        else:
            step = -np.linalg.solve(_damped(hess, damping), grad[..., None])[..., 0]
        step = np.where(active[:, None], step, 0.0)
        trial = x.copy()
        trial[:, cols] += step
        new_cost = evaluate(body, terms, trial, system=False)[0]
        predicted = -(2 * np.sum(grad * step, axis=1) + np.sum(step * (hess @ step[..., None])[..., 0], axis=1))
        if coupled:
            gain = np.full(batch, (cost.sum() - new_cost.sum()) / max(abs(predicted.sum()), 1e-300))
            better = np.full(batch, new_cost.sum() <= cost.sum()) & active
        else:
            gain = (cost - new_cost) / np.maximum(np.abs(predicted), 1e-300)
            better = (new_cost <= cost) & active
        decrease = (cost - new_cost) / np.maximum(cost, 1e-300)
        if coupled:
            decrease = np.full(batch, (cost.sum() - new_cost.sum()) / max(cost.sum(), 1e-300))
        small = np.max(np.abs(step), axis=1) < step_tol
        if coupled:  # bodies that share columns stop together (a stopped body would keep stale shared values)
            small = np.full(batch, bool(small.all()))
        x = np.where(better[:, None], trial, x)
        factor = np.maximum(1 / 3, 1 - (2 * np.clip(gain, 0, 1) - 1) ** 3)
        damping = np.where(better, np.maximum(damping * factor, 1e-9), np.where(active, damping * growth, damping))
        growth = np.where(better, 2.0, np.where(active, growth * 2, growth))
        done = (better & ((decrease < tol) | small)) | (active & (damping > 1e8))
        converged |= done
        if converged.all():
            break
        if better.any():
            cost_new, hess_new, grad_new = evaluate(body, terms, x)
            cost = np.where(better, cost_new, cost)
            hess = np.where(better[:, None, None], hess_new, hess)
            grad = np.where(better[:, None], grad_new, grad)
    return x, cost, converged, iterations
