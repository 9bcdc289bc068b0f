"""Fit a model to 3D joints (e.g. HumanML3D's 22 = SMPL's first 22 joints, mocap skeletons).

Initial rotations come from the bones: each joint's world rotation aligns its rest bones to its
children's target directions (Procrustes over two or more children, the smallest rotation for one;
twist inherited from the parent), then shape and translation by linear least squares; Levenberg–Marquardt
on the exact Jacobian refines, with a pose prior (pulling towards the rest pose) that fixes the twists
joints cannot see, and optional temporal smoothness over a sequence.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.fit import checks
from smplcore.fit.body import FitBody, pose_points
from smplcore.fit.bones import bone_report, warn_unreachable
from smplcore.fit.gauss_newton import refine
from smplcore.fit.initialize import shape_and_translation
from smplcore.fit.joint_init import initial_state, joint_shape_and_translation
from smplcore.fit.plausibility import TOLERANCE, assess, warn_implausible
from smplcore.fit.prior_terms import PoseTerms, gmm_prior
from smplcore.fit.result import FitResult, params_to_state, single_threaded_blas, state_to_params
from smplcore.fit.solver import Objective, State, _columns, normal_equations, residual_cost
from smplcore.fit.temporal import Temporal, one_person, unwrap_rotations
from smplcore.fit.vertices import _weights, coefficient_masks

#: Default weight of the joint limits in :func:`fit_joints` (m² per rad²).
JOINT_LIMITS_WEIGHT = 1.0
#: Default weight of a pose mixture in :func:`fit_joints` (m² per nat), when one is given.
GMM_WEIGHT = 1e-4


def joint_points(body: FitBody, joint_names: Any, count: int) -> np.ndarray:
    """Point ids (into the fitting arrays' vertices + joints) of the named output joints."""
    names = body.output_joint_names
    if joint_names is None:
        if count > len(names):
            raise ShapeError(f"joints: {count} joints given, the model has {len(names)} output joints")
        picked = list(range(count))
    else:
        if isinstance(joint_names, str) or not hasattr(joint_names, "__iter__"):
            raise TypeError(f"joint_names: expected a sequence of joint names, got {type(joint_names).__name__}")
        joint_names = list(joint_names)
        if any(not isinstance(n, str) for n in joint_names):
            raise TypeError(f"joint_names: expected model joint names (str), got {joint_names[:3]!r}...")
        if len(joint_names) != count:
            raise ShapeError(f"joint_names: {len(joint_names)} names for {count} joints")
        lookup = {n: i for i, n in enumerate(names)}
        unknown = [n for n in joint_names if n not in lookup]
        if unknown:
            raise ValueError(f"joint_names: {unknown} are not joints of this model (its joints: model.joint_names)")
        picked = [lookup[n] for n in joint_names]
    ids = []
    for i in picked:
        row = body.output_rows[i]
        nonzero = np.flatnonzero(row)
        if len(nonzero) != 1 or row[nonzero[0]] != 1.0:
            raise ValueError(
                f"joint_names: {names[i]!r} is a landmark (a combination of vertices), which fit_joints does not fit"
            )
        ids.append(int(nonzero[0]))
    return np.asarray(ids, np.int64)


@single_threaded_blas
def fit_joints(
    model: Any,
    joints: Any,
    joint_names: Any = None,
    joint_weights: Any = None,
    *,
    betas: Any = None,
    fit_betas: bool = True,
    share_betas: bool | None = None,
    fit_transl: bool = True,
    shape_prior: float = 1e-4,
    pose_prior: float = 1e-4,
    joint_limits: float = JOINT_LIMITS_WEIGHT,
    bending: float = 0.0,
    gmm: Any = "auto",
    gmm_weight: float = GMM_WEIGHT,
    smoothness: float = 0.0,
    init: dict[str, Any] | None = None,
    max_iter: int = 30,
    tol: float = 1e-2,
    smoothing_rounds: int = 6,
    workers: int | None = None,
) -> FitResult:
    """Parameters of ``model`` whose joints match 3D joint positions.

    Parameters
    ----------
    model : a torch model of :func:`smplcore.create` or a :class:`smplcore.BodyModel`.
    joints : (B, n, 3) target joints (metres); a sequence is B = T frames. NaN marks a missing joint (a
        marker lost in some frames): it is left out of that body's fit (``mask``); a body needs 3 joints.
    joint_names : the model's output-joint names of the n targets (``model.joint_names``); default the
        first n output joints (SMPL's first 22 for HumanML3D). Skeleton joints and vertex joints (nose,
        toes, fingertips) can be fitted; landmarks cannot.
    joint_weights : (n,) or (B, n) non-negative weights (zero for unused joints).
    betas, fit_betas, fit_transl, init : as in :func:`fit_vertices`.
    share_betas : one set of betas for the whole batch (one person in many frames). None (the default)
        shares them when the targets are one person's: every bone between a target joint and its parent's
        target keeps its length over the batch (within 1 cm or 2 %, 5th to 95th percentile; a mocap
        skeleton's bones are fixed). Different people, or estimates whose bones wander, are fitted one
        shape each; pass True or False to decide.
    shape_prior : weight of Σ β² (m² per unit²): joints alone determine shape weakly.
    pose_prior : weight of Σ θ² (m² per rad²): fixes the twists that joints do not determine (about
        bones with one observed child, and joints without observed children) at the rest pose's.
    joint_limits : weight (m² per rad²) of the anatomical joint limits (:data:`smplcore.fit.priors.JOINT_LIMITS`;
        elbows and knees bend one way): strong enough that a target the model cannot reach with a plausible
        pose (a torso shorter than the shape space holds) is missed rather than met by folding the spine.
        0 turns them off.
    bending : weight of the elbow/knee hinge prior alone (the limits hold it already).
    gmm, gmm_weight : a pose mixture (:class:`GMMPrior`, a path to SMPLify's ``gmm_08.pkl``, ``"open"`` for
        smplcore's own when installed, or None) and its weight (m² per nat). ``"auto"`` (the default) takes
        the open mixture where it helps: when some target bones lie outside what the shape space reaches
        (``result.bones``), so that the pose stays natural, not only within its limits, where the joints
        cannot be met; otherwise none.
    smoothness : weight of the changes of pose, translation (and shape, when not shared) between consecutive
        bodies of the batch (a sequence, in order), relative to the joints: each parameter's change costs
        ``smoothness`` times what moving the targets' joints by that change costs
        (:meth:`smplcore.fit.temporal.Temporal.relative`), so it acts as a weight on the joints' velocities.
        The coupled system is solved at once (:mod:`smplcore.fit.temporal`); rotations are made continuous
        along the sequence first. 0 (the default) fits
        each body on its own; 1 to 3 halves centimetre noise (on 40 frames of a turning body).
    smoothing_rounds : kept for compatibility (checked, no longer used: the coupled system needs no rounds).
    max_iter, tol : Levenberg–Marquardt iterations and relative cost decrease to stop at. The default
        (30, 1e-2) stops after about 2 iterations on clean joints, within 0.01 mm of the tighter optimum
        (``tol=1e-8``, 2-3× slower); ``max_iter=0`` keeps the closed-form start (bones, then shape and
        translation): fastest, ~0.4 mm further from the optimum on HumanML3D-like poses.
    workers : threads sharing the bodies' work (None: one per core; 1: this thread only).

    Returns
    -------
    FitResult with ``params``, ``joint_error`` (B,) (metres, mean over the joints used), ``point_error``
    (B, n) and ``mask`` (B, n), and ``plausibility`` (body joints outside their anatomical limits; an
    :class:`ImplausibleFitWarning` names them). Targets whose size is more than 10x off the model's
    (millimetres, centimetres) are refused with a ValueError naming ``joints``; bodies left further from
    their targets than half the targets' spread are flagged not converged, with a warning; a fit that
    would come out non-finite raises :class:`smplcore.fit.FitError` (never a NaN result).

    Examples
    --------
    >>> import numpy as np, smplcore
    >>> from smplcore import fit
    >>> model = smplcore.BodyModel(model_type="open")
    >>> target = model(body_pose=np.full((2, 69), 0.2)).joints[:, :22]
    >>> r = fit.fit_joints(model, target)
    >>> bool(r.joint_error.max() < 0.005)
    True
    """
    body = FitBody.from_model(model)
    weights_ = checks.options(
        "weight",
        dict(shape_prior=shape_prior, pose_prior=pose_prior, joint_limits=joint_limits, bending=bending,
             gmm_weight=gmm_weight, smoothness=smoothness),
    )  # fmt: skip
    shape_prior, pose_prior, smoothness = weights_["shape_prior"], weights_["pose_prior"], weights_["smoothness"]
    tol = checks.positive("tol", tol)
    max_iter, smoothing_rounds = checks.options(
        "iterations", {"max_iter": max_iter, "smoothing_rounds": smoothing_rounds}
    ).values()
    workers = checks.workers(workers)
    init = checks.init_params(init, body)
    jt, present = target_joints(joints)
    batch, count = jt.shape[:2]
    ids = joint_points(body, joint_names, count)
    weights = _weights(joint_weights, "joint_weights", batch, count) * present
    few = np.flatnonzero((weights > 0).sum(1) < 3)
    if len(few):
        raise ValueError(
            f"joints, joint_weights: bodies {few[:10].tolist()} ({len(few)} of {batch}) have fewer than 3 joints "
            "present with positive weight (NaN marks a missing joint); every body needs at least 3 joints"
        )
    rest = pose_points(body, body.points(ids), body.full_pose(np.zeros((1, body.num_pose))),
                       np.zeros((1, body.num_coeffs)), np.zeros((1, 3))).points[0]  # fmt: skip
    checks.check_scale("joints", jt, rest, weights > 0)
    if share_betas is None:  # one person (bones of one length throughout): one shape
        share_betas = one_person(jt, weights > 0, _rigid_bones(body, ids))
    free, shared = coefficient_masks(body, fit_betas, False, bool(share_betas))
    start = params_to_state(body, {**(init or {}), **({} if betas is None else {"betas": betas})}, batch)
    prior = body.pose_prior_weights(pose_prior)
    bones = bone_report(model, jt, weights > 0, _names(body, joint_names, count))
    if isinstance(gmm, str) and gmm == "auto":
        gmm = "open" if bones is not None and bones.out_of_reach else None
    terms = PoseTerms.of(body, weights_["joint_limits"], weights_["bending"], gmm_prior(gmm), weights_["gmm_weight"])
    obj = Objective(body.points(ids), jt, weights, free, shared, fit_transl, shape_prior, prior, pose_terms=terms)
    state = start if init is not None else _start(body, ids, obj, start, clip=max_iter > 0)
    temporal = None
    if smoothness and batch > 1:
        state.pose = unwrap_rotations(body, state.pose)  # consecutive rotations as consecutive parameters
        temporal = _temporal(body, obj, state, smoothness)
        obj = Objective(**{**obj.__dict__, "temporal": temporal})
    dtype = np.float64  # 22 points: precision is free
    state, _, _, converged, iterations = refine(
        body, obj, state, dtype=dtype, max_iter=max_iter, tol=tol, workers=workers
    )
    posed = pose_points(body, body.points(ids), body.full_pose(state.pose), state.coeffs, state.transl).points
    mask = weights > 0
    dist = np.linalg.norm(posed - jt, axis=-1)
    error = (dist * mask).sum(1) / mask.sum(1)
    converged = checks.flag_gross(converged, error, checks.spread_of(jt, mask), "fit_joints", "m")
    params = state_to_params(body, model, state)
    result = FitResult(
        params=params,
        joint_error=error,
        converged=converged,
        iterations=iterations,
        point_error=np.where(mask, dist, np.nan),
        mask=mask,
        plausibility=assess(body, _body_pose(body, state)),
        bones=bones,
    )
    result = checks.finite_result(result, "fit_joints")
    warn_unreachable(result.bones, "fit_joints")
    warn_implausible(result.plausibility, "fit_joints")
    return result


def _start(body: FitBody, ids: np.ndarray, obj: Objective, start: State, clip: bool = True) -> State:
    """The closed-form start (:mod:`smplcore.fit.joint_init`); with joint limits (and ``clip``: the solver runs
    from it), also that start with the body joints clipped into their limits (shape and translation solved
    again), each body taking the one of lower cost: a target bent past the limits is approached from inside
    them."""
    state = initial_state(body, ids, obj, start)
    terms = obj.pose_terms
    if terms is None or not terms.limits or not clip:
        return state
    clipped = state.copy()
    slack = np.radians(TOLERANCE)  # a start a little past a limit is left (a twist the bones do not show)
    clipped.pose[:, terms.cols] = np.clip(state.pose[:, terms.cols], terms.lo - slack, terms.hi + slack)
    clipped = shape_and_translation(body, obj, clipped)
    better = residual_cost(body, obj, clipped) < residual_cost(body, obj, state)
    if not better.any():
        return state
    state.put(np.flatnonzero(better), clipped.take(np.flatnonzero(better)))
    return joint_shape_and_translation(body, obj, state) if obj.shared.any() else state


def target_joints(joints: Any) -> tuple[np.ndarray, np.ndarray]:
    """(B, n, 3) float64 targets with missing joints (NaN in any coordinate) set to zero, and (B, n) which
    are present; infinite values and bodies with no joint at all are refused, naming ``joints``."""
    if hasattr(joints, "detach"):
        joints = joints.detach().cpu().numpy()
    try:
        jt = np.array(joints, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"joints: expected a numeric array, got {type(joints).__name__}") from exc
    if jt.ndim == 2:
        jt = jt[None]
    if jt.ndim != 3 or jt.shape[2] != 3:
        raise ShapeError(f"joints: expected (B, n, 3), got {tuple(np.shape(joints))}")
    batch, count = jt.shape[:2]
    checks.nonempty_batch("joints", batch)
    if count < 3:
        raise ShapeError(f"joints: expected at least 3 joints per body, got {count}")
    if np.isinf(jt).any():
        raise ValueError(f"joints: {int(np.isinf(jt).sum())} infinite value(s); mark a missing joint with NaN")
    present = np.logical_not(np.isnan(jt).any(axis=-1))
    empty = np.flatnonzero(~present.any(axis=1))
    if len(empty):
        raise ValueError(
            f"joints: bodies {empty[:10].tolist()} ({len(empty)} of {batch}) are all NaN (no joint present); "
            "drop those frames"
        )
    jt[~present] = 0.0
    return jt, present


def _body_pose(body: FitBody, state: State) -> np.ndarray:
    """(B, 3 J) the ``body_pose`` block of a state ((B, 0) for models without one)."""
    for block in body.blocks:
        if block.name == "body_pose":
            return state.pose[:, block.start : block.start + block.width]
    return state.pose[:, :0]


def _temporal(body: FitBody, obj: Objective, state: State, smoothness: float) -> Temporal:
    """The temporal term over the pose, translation and unshared shape, ``smoothness`` relative to the data's
    stiffness on each column (the median over the bodies of the diagonal of the points' Gauss–Newton matrix
    at ``state``)."""
    q, k = body.num_pose, body.num_coeffs
    data = Objective(obj.points, obj.targets, obj.weights, obj.free_coeffs, obj.shared, obj.fit_transl)
    hess, _, _ = normal_equations(body, data, state)
    assert hess is not None  # asked for
    cols = _columns(body, data)
    stiffness = np.median(np.einsum("bii->bi", hess), axis=0)
    coeff = (cols >= q) & (cols < q + k)
    smoothed = ~coeff | ~obj.shared[np.clip(cols - q, 0, k - 1)]  # and each body's own shape
    return Temporal.relative(smoothness, stiffness[smoothed], cols[smoothed])


def _names(body: FitBody, joint_names: Any, count: int) -> list[str]:
    """The model joint names of the targets."""
    return list(body.output_joint_names[:count]) if joint_names is None else list(joint_names)


def _rigid_bones(body: FitBody, ids: np.ndarray) -> list[tuple[int, int]]:
    """Pairs (into the targets) of a skeleton joint and its parent, both targets: bones of one length."""
    row = {int(p) - body.num_vertices: i for i, p in enumerate(ids) if p >= body.num_vertices}
    return [(row[j], row[int(body.parents[j])]) for j in row if body.parents[j] >= 0 and int(body.parents[j]) in row]
