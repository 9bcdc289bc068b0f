"""Fit a body model to 2D keypoints seen by a known pinhole camera (SMPLify-style, without registration).

Stages: (1) the body in its rest pose, the translation from the torso's size in the image and the
focal length, then translation and global orientation fitted to the torso and head keypoints, from
two starts (facing the camera and facing away; the better is kept); (2) everything (pose, shape,
translation) with the priors, whose weights decrease over a few rounds (from ``anneal``), as SMPLify
does. With ``estimate_focal`` both stages run for several focal lengths and the best is refined jointly
with the bodies (:mod:`smplcore.fit.focal`). See :mod:`smplcore.fit.reprojection` for the objective,
:mod:`smplcore.fit.priors` and :mod:`smplcore.fit.vposer` for the priors.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.fit import checks
from smplcore.fit.body import FitBody
from smplcore.fit.camera import Camera
from smplcore.fit.focal import FOCAL_PRIOR, estimate_focal_length
from smplcore.fit.placement import HEAD, TORSO, place
from smplcore.fit.plausibility import assess, warn_implausible
from smplcore.fit.prior_terms import gmm_prior
from smplcore.fit.priors import BENDING, GMMPrior, joint_limits
from smplcore.fit.reprojection import KeypointMap, Terms, levenberg_marquardt, reprojection
from smplcore.fit.result import FitResult, as_array, params_to_state, single_threaded_blas, state_to_params
from smplcore.fit.solver import State
from smplcore.fit.visibility import keypoint_weights, warn_unseen, weighted_error
from smplcore.fit.vposer import POSE_WIDTH, VPoserPrior

__all__ = ["HEAD", "TORSO", "fit_keypoints", "keypoint_map"]

#: The body's own points the upright prior reads (:mod:`smplcore.fit.reprojection`), pelvis first.
GUIDES = ("pelvis", "spine1", "neck")
#: Default weight of the upright prior (m² per m² of lean along the line of sight).
UPRIGHT = 3e-2
#: The upright prior's weight is this many times larger for bodies whose legs are not seen.
UNSEEN_LEGS = 10.0


def keypoint_map(body: FitBody, model: Any, convention: Any, regressor: Any = None) -> KeypointMap:
    """How the keypoints of ``convention`` are made from ``model``'s points (its output joints by name,
    midpoints where the convention defines them so, or the rows of a :class:`~smplcore.keypoints.Regressor`)."""
    from smplcore import keypoints

    try:
        dst = keypoints.layout(convention, "convention")
    except (KeyError, ValueError, TypeError) as exc:
        raise ValueError(
            f"convention: unknown keypoint convention {convention!r}; use one of {keypoints.conventions()} "
            "or a list of point names"
        ) from exc
    width = body.num_vertices + body.num_joints
    if regressor is None:
        plan = keypoints.plan(model, dst)
        rows = body.output_rows
    else:
        if not hasattr(regressor, "num_vertices") or not hasattr(regressor, "matrix"):
            raise TypeError(f"regressor: expected a smplcore.keypoints.Regressor, got {type(regressor).__name__}")
        if regressor.num_vertices != body.num_vertices:
            raise ShapeError(
                f"regressor: made for {regressor.num_vertices} vertices, the model has {body.num_vertices}"
            )
        plan = keypoints.plan(
            list(regressor.qualified_names()) if hasattr(regressor, "qualified_names") else list(regressor.names), dst
        )
        mat = regressor.matrix
        mat = np.asarray(mat.toarray() if hasattr(mat, "toarray") else mat, np.float64)
        rows = np.concatenate([mat, np.zeros((len(mat), body.num_joints))], axis=1)
    full = np.zeros((len(dst), width))
    first, second = np.where(plan.mask, plan.first, 0), np.where(plan.mask, plan.second, 0)
    full[plan.mask] = 0.5 * (rows[first[plan.mask]] + rows[second[plan.mask]])
    available = plan.mask & full.any(axis=1)
    if not available.any():
        raise ValueError(f"convention: none of the points of {dst.label} is a point of this model")
    names = body.output_joint_names
    guide = np.zeros((0, width))
    if all(n in names for n in GUIDES):
        guide = body.output_rows[[names.index(n) for n in GUIDES]]
    ids = np.flatnonzero(full.any(axis=0) | guide.any(axis=0))
    return KeypointMap(body.points(ids), full[:, ids], available, dst.names, guide[:, ids] if len(guide) else None)


def _check_keypoints(keypoints: Any, num: int, label: str) -> np.ndarray:
    kp = as_array(keypoints, "keypoints")
    if kp.ndim == 2:
        kp = kp[None]
    if kp.ndim != 3 or kp.shape[1:] != (num, 3):
        raise ShapeError(
            f"keypoints: expected (B, {num}, 3) x, y (pixels), confidence for convention {label}, "
            f"got {tuple(np.shape(keypoints))}"
        )
    return kp


def _natural_pose(body: FitBody, block: Any) -> np.ndarray:
    """(D,) body pose with the arms lowered (0.8 rad) and elbows (0.5) and knees (0.3) bent forward."""
    names = body.output_joint_names[block.first_joint : block.first_joint + block.num_joints]
    pose = np.zeros(block.width)
    for joint, axis, value in (
        ("left_shoulder", 2, -0.8), ("right_shoulder", 2, 0.8), ("left_elbow", 1, -0.5),
        ("right_elbow", 1, 0.5), ("left_knee", 0, 0.3), ("right_knee", 0, 0.3),
    ):  # fmt: skip
        if joint in names:
            pose[names.index(joint) * 3 + axis] = value
    return pose


def _terms(body, kmap, camera, targets, weights, scale, sigma, free, shared, **priors) -> Terms:
    """The terms of a round (see :class:`~smplcore.fit.reprojection.Terms`)."""
    q, k = body.num_pose, body.num_coeffs
    blocks = {b.name: b for b in body.blocks}
    bp = blocks["body_pose"]
    body_cols = np.arange(bp.start, bp.start + bp.width)
    names = body.output_joint_names[bp.first_joint : bp.first_joint + bp.num_joints]
    lo, hi = joint_limits(names)
    bend = [(names.index(n) * 3 + axis, sign) for n, axis, sign in BENDING if n in names]
    smooth_cols = np.concatenate([np.arange(q), q + k + np.arange(3)])
    return Terms(
        kmap=kmap,
        camera=camera,
        targets=targets,
        weights=weights,
        scale=scale,
        sigma=sigma,
        free=free,
        shared=shared,
        beta_cols=q + np.flatnonzero(free[q : q + body.num_betas]),
        body_cols=body_cols,
        lo=lo.reshape(-1),
        hi=hi.reshape(-1),
        bend_index=np.array([i for i, _ in bend], np.int64),
        bend_sign=np.array([s for _, s in bend]),
        smooth_cols=smooth_cols,
        **priors,
    )


@dataclass
class _Setup:
    """What stages 1 and 2 need besides the camera."""

    body: FitBody
    kmap: KeypointMap
    start: State
    given: dict[str, Any]
    targets: np.ndarray
    weights: np.ndarray
    free: np.ndarray
    shared: np.ndarray
    sigma: float
    priors: dict[str, float]  # annealed
    fixed: dict[str, Any]  # not annealed
    anneal: tuple[float, ...]
    starts: list[np.ndarray | None] = field(default_factory=lambda: [None])  # body poses of stage 2's starts
    max_iter: int = 25
    tol: float = 1e-4
    upright: np.ndarray | float = 0.0  # (B,) or one weight
    up: np.ndarray | None = None


def _stages(setup: _Setup, camera: Camera, scale: np.ndarray | None = None):
    """Stages 1 and 2 with ``camera``. Returns the state, (B,) costs, converged flags, iterations, the
    last round's terms and the (B,) metres per pixel used (``scale`` when given)."""
    body, batch = setup.body, len(setup.targets)
    q, k = body.num_pose, body.num_coeffs
    blocks = {b.name: b for b in body.blocks}
    go, bp = blocks["global_orient"], blocks["body_pose"]

    def stage1_terms(cam, targets, weights, scale1, free, upright):
        return _terms(body, setup.kmap, cam, targets, weights, scale1, setup.sigma, free, np.zeros_like(free),
                      upright=upright, up=_up(cam, setup.up))  # fmt: skip

    placed, scale, iterations = place(
        setup, camera, stage1_terms, np.arange(go.start, go.start + 3), q + k + np.arange(3), scale
    )
    coupled = bool(setup.shared.any() or setup.fixed.get("smooth")) and batch > 1
    best: tuple[State, np.ndarray, np.ndarray] | None = None
    for pose in setup.starts:
        state = placed.copy()
        if pose is not None:
            state.pose[:, bp.start : bp.start + bp.width] = pose
        for factor in setup.anneal:
            terms = _terms(
                body, setup.kmap, camera, setup.targets, setup.weights, scale, setup.sigma, setup.free, setup.shared,
                **{key: value * factor for key, value in setup.priors.items()}, **setup.fixed,
                upright=setup.upright, up=_up(camera, setup.up),
            )  # fmt: skip
            state, cost, converged, used = levenberg_marquardt(
                body, terms, state, max_iter=setup.max_iter, tol=setup.tol
            )
            iterations += used
        if best is None:
            best = (state, cost, converged)
            continue
        better = np.full(batch, cost.sum() < best[1].sum()) if coupled else cost < best[1]
        best = (_where(better, state, best[0]), np.where(better, cost, best[1]), np.where(better, converged, best[2]))
    assert best is not None  # starts holds at least one pose
    return (*best, iterations, terms, scale)


def _check_up(up: Any) -> np.ndarray | None:
    """``up`` as a unit (3,) direction, or None."""
    if up is None:
        return None
    value = as_array(up, "up")
    if value.shape != (3,) or not np.linalg.norm(value) > 0:
        raise ValueError(f"up: expected a non-zero (3,) direction (the world's up), got {np.asarray(up).tolist()}")
    return value / np.linalg.norm(value)


def _up(camera: Camera, up: np.ndarray | None) -> np.ndarray:
    """The world's up direction (3,): ``up``, or the camera's −y axis (a level camera's up)."""
    return camera.rotation.T @ np.array([0.0, -1.0, 0.0]) if up is None else up


def _where(mask: np.ndarray, a: State, b: State) -> State:
    """Per body, ``a`` where ``mask`` else ``b``."""
    return State(*(np.where(mask[:, None], getattr(a, f), getattr(b, f)) for f in ("pose", "coeffs", "transl")))


@single_threaded_blas
def fit_keypoints(
    model: Any,
    keypoints: Any,
    convention: Any = "coco17",
    camera: Camera | None = None,
    *,
    regressor: Any = None,
    betas: Any = None,
    fit_betas: bool = True,
    share_betas: bool = False,
    init: dict[str, Any] | None = None,
    min_confidence: float = 0.1,
    min_points: int = 6,
    sigma: float = 100.0,
    shape_prior: float = 1e-3,
    pose_prior: float = 1e-5,
    joint_limits: float = 100.0,
    bending: float = 1.0,
    gmm: str | os.PathLike[str] | GMMPrior | None = None,
    gmm_weight: float = 1e-4,
    vposer: str | os.PathLike[str] | VPoserPrior | None = None,
    vposer_weight: float = 1e-4,
    estimate_focal: bool = False,
    focal_prior: float = FOCAL_PRIOR,
    smoothness: float = 0.0,
    upright: float = UPRIGHT,
    up: Any = None,
    anneal: tuple[float, ...] = (3.0, 1.0),
    multi_start: bool = True,
    max_iter: int = 25,
    tol: float = 1e-4,
) -> FitResult:
    """Parameters of ``model`` whose keypoints, seen by ``camera``, match 2D detections.

    Parameters
    ----------
    model : a torch model of :func:`smplcore.create` or a :class:`smplcore.BodyModel` with a body
        (SMPL, SMPL+H, SMPL-X or the open model).
    keypoints : (B, K, 3) x, y (pixels), confidence; B independent bodies (people, frames).
    convention : the keypoints' convention (``"coco17"``, ``"openpose25"``, ... see
        :func:`smplcore.keypoints.conventions`) or a list of point names.
    camera : a :class:`Camera` (OpenCV convention; ``Camera.from_image_size`` when only the image size
        is known). The body's ``transl`` is fitted in the camera's world frame.
    regressor : a :class:`smplcore.keypoints.Regressor` giving the keypoints from the vertices instead of
        the model's joints (e.g. :func:`smplcore.keypoints.open_model_regressor`).
    betas, fit_betas, share_betas, init : as in :func:`fit_vertices`; ``share_betas`` for one person
        over a sequence.
    min_confidence : keypoints below it are ignored, and so are keypoints outside the image when the camera
        knows its ``image_size`` (a detector's guesses for what the image cuts off); the others are
        weighted by their confidence. Parts without keypoints stay at the priors: legs not seen are
        standing (with a warning, "legs not visible").
    min_points : keypoints each body needs at least (1 or more).
    sigma : Geman–McClure scale (pixels).
    shape_prior, pose_prior : weights of Σ β² and Σ θ² (body pose; m² per unit).
    joint_limits, bending : weights (m² per rad²) of the anatomical joint limits and of the elbow/knee
        bending prior (:mod:`smplcore.fit.priors`).
    gmm, gmm_weight : a pose mixture (a :class:`GMMPrior`, a path to SMPLify's ``gmm_08.pkl``, or ``"open"`` for
        smplcore's open prior, :meth:`GMMPrior.open`; default None) and its weight. ``gmm="open"`` is recommended
        for real images: it lowers PA-MPJPE on held-out real mocap seen through cameras (73 -> 63 mm, COCO-17,
        whole body in view) and on the synthetic bench (36.6 -> 34.0 mm).
    vposer, vposer_weight : VPoser v2 (the ``V02_05`` folder, its ``.ckpt``, or a :class:`VPoserPrior`) and
        the weight of ``|μ(θ)|²``, its encoder's mean of the first 21 body joints' rotations.
    estimate_focal : fit one focal length for the whole batch (every body is seen by ``camera``):
        stages 1 and 2 for each of the focal lengths ``camera.focal × FOCAL_GRID``, the best (with the
        prior) refined jointly with the bodies (:mod:`smplcore.fit.focal`); ``focal_prior`` is the weight
        of ``(log f/f₀)²`` (m², as the other priors) pulling it towards ``camera.focal``; the aspect
        ratio f_y/f_x is kept. The result's ``camera`` holds the estimate. About six times the time.
    smoothness : weight of Σ_t |x_t − x_{t−1}|² over pose and translation of consecutive bodies.
    upright, up : weight (m² per m²) of the upright prior (:mod:`smplcore.fit.reprojection`), which keeps
        the body from leaning towards or away from the camera where the keypoints do not decide it, and
        the world's up direction (3,) it uses; default the camera's −y axis in the world (a level camera:
        the image's up). Give ``up`` when the camera is tilted and its rotation says so.
    anneal : multipliers of the priors' weights in the rounds of stage 2.
    multi_start : run stage 2 also from a natural pose (arms lowered, elbows and knees a little bent)
        and keep, per body, the fit with the lower cost (about twice the time).
    max_iter, tol : Levenberg–Marquardt iterations per round and relative decrease to stop at.

    Returns
    -------
    FitResult with ``params``, ``reprojection_error`` (B,) confidence-weighted mean pixels over the
    keypoints used, ``point_error`` (B, K) pixels of each keypoint (NaN where not used), ``mask`` (B, K) the
    keypoints used, ``plausibility`` (body joints outside their anatomical limits; an
    :class:`~smplcore.fit.plausibility.ImplausibleFitWarning` names them),
    ``converged`` (B,) and ``camera`` (the given one, or with the estimated focal length). Bodies whose mean
    reprojection error exceeds half their keypoints' spread are flagged not converged, with a warning; a fit
    that would come out non-finite raises :class:`smplcore.fit.FitError` (never a NaN result).
    """
    if camera is None:
        raise ValueError(
            "camera: fit_keypoints needs the camera, e.g. fit.Camera(focal=f, center=(cx, cy)) or "
            "fit.Camera.from_image_size(width, height)"
        )
    if not isinstance(camera, Camera):
        raise TypeError(f"camera: expected a smplcore.fit.Camera, got {type(camera).__name__}")
    body = FitBody.from_model(model)
    weights_ = checks.options("weight", dict(
        min_confidence=min_confidence, shape_prior=shape_prior, pose_prior=pose_prior, joint_limits=joint_limits,
        bending=bending, gmm_weight=gmm_weight, vposer_weight=vposer_weight, focal_prior=focal_prior,
        smoothness=smoothness, upright=upright,
    ))  # fmt: skip
    (min_confidence, shape_prior, pose_prior, joint_limits, bending, gmm_weight, vposer_weight, focal_prior,
     smoothness, upright) = weights_.values()  # fmt: skip
    up_dir = _check_up(up)
    sigma, tol = checks.positive("sigma", sigma), checks.positive("tol", tol)
    max_iter = checks.count("max_iter", max_iter, 0, 100_000)
    min_points = checks.count("min_points", min_points, 1)
    anneal = checks.factors("anneal", anneal)
    init = checks.init_params(init, body)
    if vposer is not None and not isinstance(vposer, (str, os.PathLike, VPoserPrior)):
        raise TypeError(f"vposer: expected a path or a smplcore.fit.VPoserPrior, got {type(vposer).__name__}")
    if not {"global_orient", "body_pose"} <= {b.name for b in body.blocks}:
        raise ValueError(f"model: fit_keypoints fits bodies; a {body.model_type} model has no body_pose")
    kmap = keypoint_map(body, model, convention, regressor)
    kp = _check_keypoints(keypoints, len(kmap.names), str(convention))
    batch = len(kp)
    checks.nonempty_batch("keypoints", batch)
    targets, conf = kp[..., :2], kp[..., 2]
    weights, outside = keypoint_weights(targets, conf, kmap.available, camera, min_confidence)
    counts = (weights > 0).sum(1)
    if np.any(counts < min_points):
        bad = np.flatnonzero(counts < min_points)
        inside = " inside the image" if camera.image_size is not None else ""
        raise ValueError(
            f"keypoints: bodies {bad.tolist()[:10]} have {counts[bad].tolist()[:10]} keypoints with confidence "
            f">= {min_confidence}{inside} that the model has (need min_points={min_points}); drop them or lower "
            "min_points"
        )
    legs = warn_unseen(kmap.names, weights, outside, "fit_keypoints")
    gmm = gmm_prior(gmm)
    q, k = body.num_pose, body.num_coeffs
    blocks = {b.name: b for b in body.blocks}
    if gmm is not None:
        gmm = gmm.marginal(blocks["body_pose"].width)
    if isinstance(vposer, (str, os.PathLike)):
        vposer = VPoserPrior.load(vposer)
    if vposer is not None:
        if not isinstance(vposer, VPoserPrior):
            raise TypeError(f"vposer: expected a path or a smplcore.fit.VPoserPrior, got {type(vposer).__name__}")
        if blocks["body_pose"].width < POSE_WIDTH:
            raise ValueError(
                f"vposer: VPoser covers 21 body joints; this {body.model_type} model's body pose has fewer"
            )
    start = params_to_state(body, {**(init or {}), **({} if betas is None else {"betas": betas})}, batch)
    bp = blocks["body_pose"]
    free = np.zeros(q + k + 3, bool)
    free[blocks["global_orient"].start + np.arange(3)] = free[q + k :] = True
    free[bp.start : bp.start + bp.width] = True
    if fit_betas:
        free[q : q + body.num_betas] = True
    shared = np.zeros_like(free)
    if share_betas and fit_betas:
        shared[q : q + body.num_betas] = True
    starts: list[np.ndarray | None] = [None]
    if multi_start and "body_pose" not in (init or {}):
        starts.append(_natural_pose(body, bp))  # stage 2 also from a natural pose (the better is kept)
    setup = _Setup(
        body, kmap, start, init or {}, targets, weights, free, shared, sigma,
        priors=dict(shape_prior=shape_prior, pose_prior=pose_prior, gmm_prior=gmm_weight, vposer_prior=vposer_weight),
        fixed=dict(limit_prior=joint_limits, bend_prior=bending, gmm=gmm, vposer=vposer, smooth=smoothness),
        anneal=anneal, starts=starts, max_iter=max_iter, tol=tol, up=up_dir,
        upright=np.where(legs, 1.0, UNSEEN_LEGS) * upright,
    )  # fmt: skip
    if estimate_focal:
        state, converged, iterations, terms = estimate_focal_length(setup, _stages, camera, focal_prior)
        camera = terms.camera
    else:
        state, _, converged, iterations, terms, _ = _stages(setup, camera)
    dist = reprojection(body, terms, state)
    visible = weights > 0
    error = weighted_error(dist, weights)
    converged = checks.flag_gross(converged, error, checks.spread_of(targets, visible), "fit_keypoints", "px")
    plausibility = assess(body, state.pose[:, bp.start : bp.start + bp.width])
    result = FitResult(
        params=state_to_params(body, model, state),
        reprojection_error=error,
        converged=converged,
        iterations=iterations,
        camera=camera,
        point_error=np.where(visible, dist, np.nan),
        mask=visible,
        plausibility=plausibility,
    )
    checks.finite_result(result, "fit_keypoints")
    warn_implausible(plausibility, "fit_keypoints")
    return result
