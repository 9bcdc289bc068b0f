"""MANO hands onto SMPL-X / SMPL+H bodies (:func:`join_hands`) and back (:func:`split_hands`).

The body's hands are MANO (same joints, same finger order, same rest frames), so a hand's finger rotations
carry over joint for joint, and its orientation becomes the body's wrist rotation through the kinematic
chain: ``wrist_local = parent_worldᵀ · hand_world``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smplcore.errors import warn
from smplcore.join._rig import RigFacts, _rig_of
from smplcore.join.body import (
    HAND_BLOCKS,
    block_axis_angle,
    copy_params,
    hand_block_value,
    joint_positions,
    local_rotations,
    rest_joints,
    rotations_as_axis_angle,
    set_joint,
    world_rotations,
)
from smplcore.join.mano import SIDES, HandRotations, ManoHand, check_camera_rotation, hand_rotations
from smplcore.join.rotations import (
    MIRROR,
    angle_between,
    mirror_axis_angle,
    mirror_matrix,
    numpy_of,
    to_axis_angle,
    to_matrix,
)
from smplcore.join.twist import forearm_axis, redistribute_twist

_BODIES = ("smplx", "smplh")


@dataclass(frozen=True)
class HandResidual:
    """How well the body's hand reproduces the given one (arrays of shape (B,), radians and metres).

    Attributes
    ----------
    side : ``"left"`` or ``"right"``.
    wrist_angle : angle between the body's wrist orientation (world) and the hand's.
    finger_angle : largest angle, over the 15 finger joints, between the body's local rotation and the hand's
        (non-zero when the body's PCA space cannot hold the pose).
    pca_residual : norm of the part of the finger pose (axis-angle, 45 values) outside the body's PCA space.
    wrist_offset : distance between the body's wrist joint and the MANO wrist, or None (needs the hand's
        ``model`` and ``transl``; the body's ``betas``/``transl`` as given).
    forearm_twist_before, forearm_twist_after : the wrist's twist about the forearm (signed angle) before and
        after the forearm adjustment (equal without it).
    """

    side: str
    wrist_angle: np.ndarray
    finger_angle: np.ndarray
    pca_residual: np.ndarray
    wrist_offset: np.ndarray | None
    forearm_twist_before: np.ndarray
    forearm_twist_after: np.ndarray

    @property
    def max_angle(self) -> float:
        """The largest wrist or finger angle over the batch (radians)."""
        return float(max(np.max(self.wrist_angle), np.max(self.finger_angle)))


@dataclass(frozen=True)
class JoinResult:
    """``params``: the body parameters with the hands joined (float64 NumPy arrays, the body model's keywords);
    ``residuals``: a :class:`HandResidual` (or :class:`smplcore.join.HeadResidual`) per joined part."""

    params: dict[str, Any]
    residuals: dict[str, Any] = field(default_factory=dict)


def _body_rig(body_model: Any) -> RigFacts:
    rig = _rig_of(body_model)
    if rig.model_type not in _BODIES:
        raise ValueError(f"body_model: expected an SMPL-X or SMPL+H model (with hands), got a {rig.model_type} model")
    return rig


def join_hands(
    body_model: Any,
    body_params: dict[str, Any],
    left: ManoHand | dict | None = None,
    right: ManoHand | dict | None = None,
    *,
    forearm_twist: float = 0.0,
    forearm_twist_limit: float = np.pi / 2,
) -> JoinResult:
    """Put MANO hands on an SMPL-X / SMPL+H body: its wrist rotations and hand poses.

    Parameters
    ----------
    body_model : the body (:class:`smplcore.BodyModel` or ``smplcore.create(...)``); its options (``use_pca``,
        ``num_pca_comps``, ``flat_hand_mean``) say how the result's hand poses are written.
    body_params : the body's keywords (``global_orient`` (B, 3) or (B, 3, 3), ``body_pose`` (B, 63) or
        (B, 21, 3, 3), hand poses, ``betas``, ``transl``, ...). Not modified.
    left, right : :class:`ManoHand` (or a dict of its fields) per hand to join, or None to keep the body's.
    forearm_twist : share (0..1) of the wrist's twist about the forearm moved into the elbow joint (the forearm
        turns about its own axis, as pronation does), so that LBS does not collapse the wrist ("candy
        wrapper"). The hand does not move: the wrist takes the opposite turn. 0 (default): wrist only.
    forearm_twist_limit : bound (radians) on the elbow's twist about the forearm after the adjustment.

    Returns
    -------
    :class:`JoinResult`: ``params`` (every given key, float64, rotations as axis-angle; ``body_pose`` with the
    wrists (and elbows) set, ``left_hand_pose`` / ``right_hand_pose`` in the body model's convention) and
    ``residuals`` with a :class:`HandResidual` per joined hand.
    """
    rig = _body_rig(body_model)
    if not 0.0 <= forearm_twist <= 1.0:
        raise ValueError(f"forearm_twist: expected a share in [0, 1], got {forearm_twist!r}")
    if not forearm_twist_limit >= 0:
        raise ValueError(f"forearm_twist_limit: expected a non-negative angle, got {forearm_twist_limit!r}")
    hands: dict[str, HandRotations] = {}
    for side, given in (("left", left), ("right", right)):
        if given is not None:
            hands[side] = hand_rotations(given, side, label=side)
    if not hands:
        raise ValueError("left, right: give at least one hand to join")
    params, batch = copy_params(body_params, tuple(h.orientation.shape[0] for h in hands.values()))
    rotations_as_axis_angle(rig, params, batch)
    world = world_rotations(rig, local_rotations(rig, params, batch))
    rest = rest_joints(rig, params.get("betas"), batch)
    twists = {}
    for side, hand in hands.items():
        wrist = rig.joint_names.index(f"{side}_wrist")
        elbow = int(rig.parents[wrist])
        target = np.broadcast_to(hand.orientation, (batch, 3, 3))
        wrist_local = np.swapaxes(world[:, elbow], -1, -2) @ target
        axis = forearm_axis(rest, elbow, wrist)
        elbow_local = to_matrix(_joint_axis_angle(rig, params, elbow))
        new_elbow, new_wrist, before, after = redistribute_twist(
            elbow_local, wrist_local, axis, forearm_twist, forearm_twist_limit
        )
        if forearm_twist > 0:
            set_joint(rig, params, elbow, new_elbow, batch)
        set_joint(rig, params, wrist, new_wrist, batch)
        value, outside = hand_block_value(rig, side, np.broadcast_to(hand.fingers, (batch, 45)))
        params[HAND_BLOCKS[side]] = value
        twists[side] = (before, after, outside)
    # the residuals, from the written parameters
    world = world_rotations(rig, local_rotations(rig, params, batch))
    positions = joint_positions(rig, params, world) if any(h.wrist is not None for h in hands.values()) else None
    report = {}
    for side, hand in hands.items():
        before, after, outside = twists[side]
        wrist = rig.joint_names.index(f"{side}_wrist")
        block = rig.block(HAND_BLOCKS[side])
        fingers = block_axis_angle(rig, params, block.name, batch).reshape(batch, 15, 3)
        finger_angle = angle_between(
            to_matrix(fingers), to_matrix(np.broadcast_to(hand.fingers, (batch, 45)).reshape(batch, 15, 3))
        )
        offset = None
        if hand.wrist is not None and positions is not None:
            offset = np.linalg.norm(positions[:, wrist] - hand.wrist, axis=-1)
        report[side] = HandResidual(
            side=side,
            wrist_angle=angle_between(world[:, wrist], np.broadcast_to(hand.orientation, (batch, 3, 3))),
            finger_angle=finger_angle.max(axis=1),
            pca_residual=outside,
            wrist_offset=offset,
            forearm_twist_before=before,
            forearm_twist_after=after,
        )
    return JoinResult(params, report)


def _joint_axis_angle(rig: RigFacts, params: dict[str, Any], joint: int) -> np.ndarray:
    for block in rig.pose_blocks:
        if block.first_joint <= joint < block.first_joint + block.num_joints:
            k = joint - block.first_joint
            return np.asarray(params[block.name])[:, 3 * k : 3 * k + 3]
    raise ValueError(f"joint {joint} is in no pose block")


def split_hands(
    body_model: Any,
    body_params: dict[str, Any],
    *,
    hand_models: dict[str, Any] | None = None,
    flat_hand_mean: bool = True,
    mirror_left: bool = False,
    camera_rotation: Any = None,
    camera_translation: Any = None,
) -> dict[str, ManoHand]:
    """An SMPL-X / SMPL+H body's hands as MANO parameters (the inverse of :func:`join_hands`).

    Parameters
    ----------
    body_model, body_params : the body and its keywords (as for :func:`join_hands`).
    hand_models : ``{"left": mano, "right": mano}`` (either may be missing): write that hand for that MANO
        model -- its PCA basis and mean (``use_pca``, ``num_pca_comps``, ``flat_hand_mean``), and ``transl``
        placing its wrist on the body's (zero MANO ``betas``). With ``mirror_left`` the left entry is a *right*
        model. Hands without a model are written as full (B, 45) axis-angle, flat or relative to the body
        file's mean hand pose (``flat_hand_mean``).
    flat_hand_mean : for hands without a model: True (default) writes absolute finger rotations; False writes
        them relative to the body model's mean hand pose (the MANO file's ``hands_mean``: the body's hands are
        MANO's), which needs a body model created with ``flat_hand_mean=False``.
    mirror_left : write the left hand as a right hand of the mirror image (HaMeR / WiLoR's convention).
    camera_rotation, camera_translation : world-to-camera ``R`` (3, 3) and ``t`` (3,): write ``global_orient``
        and ``transl`` in the camera frame (the mirror of ``mirror_left`` is then the image's x axis).

    Returns
    -------
    ``{"left": ManoHand, "right": ManoHand}`` with ``global_orient`` (B, 3) and ``hand_pose`` (B, 45) or
    (B, C) axis-angle, ``transl`` (B, 3) when a model is given, and the fields that say how to read them, so
    that ``join_hands(body_model, body_params, **split_hands(...))`` gives the body back.
    """
    rig = _body_rig(body_model)
    hand_models = dict(hand_models or {})
    for key in hand_models:
        if key not in SIDES:
            raise ValueError(f"hand_models: keys are 'left' and 'right', got {key!r}")
    params, batch = copy_params(body_params)
    world = world_rotations(rig, local_rotations(rig, params, batch))
    cam = check_camera_rotation(camera_rotation, "split_hands")
    positions = joint_positions(rig, params, world) if hand_models else None
    out = {}
    for side in SIDES:
        wrist = rig.joint_names.index(f"{side}_wrist")
        orient = world[:, wrist]
        fingers = block_axis_angle(rig, params, HAND_BLOCKS[side], batch)
        pos = None if positions is None else positions[:, wrist]
        if cam is not None:
            orient = cam @ orient
            if pos is not None:
                t = np.zeros(3) if camera_translation is None else numpy_of(camera_translation)
                pos = np.einsum("...ij,...j->...i", cam, pos) + t
        mirrored = side == "left" and mirror_left
        if mirrored:
            orient, fingers = mirror_matrix(orient), mirror_axis_angle(fingers)
            pos = None if pos is None else pos @ MIRROR
        model = hand_models.get(side)
        hand = ManoHand(global_orient=to_axis_angle(orient), hand_pose=fingers, mirrored=mirrored)
        if cam is not None:
            hand.camera_rotation = cam
            hand.camera_translation = camera_translation
        if model is None:
            if not flat_hand_mean:
                mean = rig.hand_means.get(HAND_BLOCKS[side])
                if mean is None or not np.any(mean):
                    raise ValueError(
                        "flat_hand_mean=False: the body model has no mean hand pose to write the hands relative "
                        "to (create it with flat_hand_mean=False, or pass hand_models)"
                    )
                if mirrored:
                    mean = mirror_axis_angle(mean)
                hand.hand_pose, hand.flat_hand_mean, hand.hand_mean = fingers - mean, False, mean
            out[side] = hand
            continue
        mano = _rig_of(model)
        expected = "right" if mirrored else side
        if (mano.model_type, mano.side) != ("mano", expected):
            raise ValueError(
                f"hand_models[{side!r}]: expected a {expected} MANO model, got {mano.model_type} ({mano.side})"
            )
        relative = fingers - mano.hand_means["hand_pose"]
        comps = mano.hand_components.get("hand_pose")
        if comps is not None:
            coeffs = np.linalg.lstsq(comps.T, relative.T, rcond=None)[0].T
            lost = float(np.linalg.norm(relative - coeffs @ comps, axis=1).max())
            if lost > 1e-6:
                warn(
                    f"split_hands: the {side} hand's pose is outside hand_models[{side!r}]'s "
                    f"{comps.shape[0]}-component PCA space by up to {lost:.3g} rad (axis-angle norm); its "
                    "coefficients are the least-squares projection (use a model with use_pca=False to keep the pose)"
                )
            relative = coeffs
        hand.hand_pose, hand.model = relative, model
        if pos is not None:
            hand.transl = pos - mano.template_joints[0]
            hand.betas = np.zeros((batch, mano.num_betas))
        out[side] = hand
    return out
