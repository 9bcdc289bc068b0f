"""MANO hand parameters: what they say (a hand's orientation and its finger rotations) in every convention
hand estimators use -- world or camera frame, full or PCA pose, flat or mean-relative, a mirrored left hand."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.join._rig import RigFacts, _rig_of
from smplcore.join.rotations import MIRROR, as_rotations, mirror_axis_angle, mirror_matrix, numpy_of, to_axis_angle

SIDES = ("left", "right")


@dataclass
class ManoHand:
    """MANO parameters of one hand, and the conventions they are in.

    Attributes
    ----------
    global_orient : (B, 3) axis-angle, or rotation matrices (B, 3, 3) / (B, 1, 3, 3): the hand's orientation
        (MANO's root joint, the wrist), in the world frame, or in the camera frame when ``camera_rotation``
        is given.
    hand_pose : the 15 finger joints: (B, 45) axis-angle, (B, C) PCA coefficients (with a PCA basis), or
        rotation matrices (B, 15, 3, 3) (absolute rotations: a flat-hand-mean convention).
    betas : (B, 10) MANO shape, or None. Used only for the wrist position (with ``transl`` and ``model``).
    transl : (B, 3) MANO translation, or None. With ``model``, joining reports how far the MANO wrist is
        from the body's.
    model : the MANO model (:class:`smplcore.BodyModel` or ``smplcore.create(model_type="mano", ...)``) the
        parameters were made for: its side, its PCA basis (``use_pca``, ``num_pca_comps``) and its mean
        (``flat_hand_mean``) say how to read ``hand_pose``. None: read ``hand_pose`` with the fields below.
    flat_hand_mean : without ``model``: True (default, HaMeR's and WiLoR's convention) when ``hand_pose`` is
        the absolute finger pose, False when it is relative to ``hand_mean``.
    hand_mean : (45,) the mean hand pose, without ``model`` and with ``flat_hand_mean=False``.
    components : (C, 45) a PCA basis (rows), without ``model``, for a (B, C) ``hand_pose``.
    mirrored : the parameters are the *other* side's model's, of the mirror image of this hand: HaMeR and
        WiLoR run a right-hand model on a horizontally flipped crop for a left hand. The mirror is x -> -x of
        the frame ``global_orient`` is given in (the image's x axis for camera-frame outputs).
    camera_rotation : (3, 3) or (B, 3, 3) world-to-camera rotation ``R`` (``x_cam = R x_world + t``), when
        ``global_orient`` (and ``transl``) are in the camera frame; None: world frame.
    camera_translation : (3,) or (B, 3) ``t`` of the same camera (for ``transl`` only).
    fix_left_shapedirs : with a left MANO ``model``, read its shape blend shapes with x negated (default True):
        the official ``MANO_LEFT.pkl`` has ``shapedirs[:, 0, :]`` with the right hand's sign (smplx#48); see
        :func:`left_shapedirs_flipped`. Only the wrist position (``betas``) depends on it.
    """

    global_orient: Any
    hand_pose: Any
    betas: Any = None
    transl: Any = None
    model: Any = None
    flat_hand_mean: bool | None = None
    hand_mean: Any = None
    components: Any = None
    mirrored: bool = False
    camera_rotation: Any = None
    camera_translation: Any = None
    fix_left_shapedirs: bool = True


def _other(side: str) -> str:
    return "left" if side == "right" else "right"


def _convention(hand: ManoHand, side: str, label: str) -> tuple[np.ndarray | None, np.ndarray, RigFacts | None]:
    """(PCA basis or None, (45,) mean, the MANO model's facts or None) of ``hand``'s ``hand_pose``."""
    if hand.model is None:
        flat = True if hand.flat_hand_mean is None else bool(hand.flat_hand_mean)
        if flat:
            mean = np.zeros(45)
        elif hand.hand_mean is None:
            raise ValueError(
                f"{label}.hand_mean: flat_hand_mean=False without a MANO model needs the mean hand pose (45,) "
                "(the MANO file's hands_mean), or pass model=<the MANO model>"
            )
        else:
            mean = np.asarray(hand.hand_mean, dtype=np.float64).reshape(-1)
            if mean.shape != (45,):
                raise ShapeError(f"{label}.hand_mean: expected shape (45,), got {np.shape(hand.hand_mean)}")
        comps = None if hand.components is None else np.asarray(hand.components, dtype=np.float64)
        if comps is not None and (comps.ndim != 2 or comps.shape[1] != 45):
            raise ShapeError(f"{label}.components: expected shape (C, 45), got {comps.shape}")
        return comps, mean, None
    if hand.flat_hand_mean is not None or hand.hand_mean is not None or hand.components is not None:
        raise ValueError(
            f"{label}: give either model= (its flat_hand_mean / use_pca options say how hand_pose is read) "
            "or flat_hand_mean / hand_mean / components, not both"
        )
    rig = _rig_of(hand.model)
    if rig.model_type != "mano":
        raise ValueError(f"{label}.model: expected a MANO model, got a {rig.model_type} model")
    expected = _other(side) if hand.mirrored else side
    if rig.side != expected:
        why = " (mirrored: the other side's model)" if hand.mirrored else ""
        raise ValueError(f"{label}.model: expected a {expected} MANO model{why}, got a {rig.side} one")
    return rig.hand_components.get("hand_pose"), rig.hand_means["hand_pose"], rig


def finger_axis_angle(hand: ManoHand, comps: np.ndarray | None, mean: np.ndarray, label: str) -> np.ndarray:
    """(B, 45) absolute finger axis-angle of ``hand`` in its own model's frame (before any mirror)."""
    pose = np.asarray(hand.hand_pose, dtype=np.float64)
    if not np.all(np.isfinite(pose)):
        raise ValueError(f"{label}.hand_pose: contains NaN or inf values")
    if pose.ndim >= 3:
        if np.any(mean):
            raise ValueError(
                f"{label}.hand_pose: rotation matrices are absolute finger rotations; they cannot be "
                "relative to a mean hand pose (flat_hand_mean=False): create the MANO model with "
                "flat_hand_mean=True (as HaMeR and WiLoR do), or pass axis-angle"
            )
        return to_axis_angle(as_rotations(f"{label}.hand_pose", pose, 15)).reshape(-1, 45)
    pose = np.atleast_2d(pose)
    if comps is not None and pose.shape[1] == comps.shape[0]:
        return pose @ comps + mean
    if pose.shape[1] != 45:
        pca = f" or ({comps.shape[0]},) PCA coefficients" if comps is not None else ""
        raise ShapeError(f"{label}.hand_pose: expected (B, 45) axis-angle{pca} or (B, 15, 3, 3), got {pose.shape}")
    return pose + mean


def check_camera_rotation(value: Any, label: str) -> np.ndarray | None:
    if value is None:
        return None
    r = numpy_of(value)
    if r.shape[-2:] != (3, 3) or r.ndim not in (2, 3):
        raise ShapeError(f"{label}.camera_rotation: expected shape (3, 3) or (B, 3, 3), got {r.shape}")
    if not np.allclose(r @ np.swapaxes(r, -1, -2), np.eye(3), atol=1e-6) or np.any(np.linalg.det(r) < 0):
        raise ValueError(f"{label}.camera_rotation: expected a rotation matrix (orthonormal, det +1)")
    return r


@dataclass(frozen=True)
class HandRotations:
    """What a :class:`ManoHand` says about a hand of ``side``, in the world frame and that side's own joints.

    ``orientation`` (B, 3, 3) the hand's world orientation; ``fingers`` (B, 45) absolute axis-angle of the 15
    finger joints (the mean added, the mirror undone); ``wrist`` (B, 3) the MANO wrist's world position, or
    None (needs ``model`` and ``transl``).
    """

    orientation: np.ndarray
    fingers: np.ndarray
    wrist: np.ndarray | None


def hand_rotations(hand: ManoHand | dict, side: str, label: str | None = None) -> HandRotations:
    """Read ``hand`` (a :class:`ManoHand` or a dict of its fields) as the rotations of a ``side`` hand."""
    if side not in SIDES:
        raise ValueError(f"side: expected 'left' or 'right', got {side!r}")
    label = label or side
    if isinstance(hand, dict):
        hand = ManoHand(**hand)
    if not isinstance(hand, ManoHand):
        raise TypeError(f"{label}: expected a ManoHand or a dict of its fields, got {type(hand).__name__}")
    arrays = ("global_orient", "hand_pose", "betas", "transl", "hand_mean", "components")
    hand = replace(hand, **{k: numpy_of(getattr(hand, k)) for k in (*arrays, "camera_rotation", "camera_translation")})
    comps, mean, rig = _convention(hand, side, label)
    fingers = finger_axis_angle(hand, comps, mean, label)
    orient = as_rotations(f"{label}.global_orient", hand.global_orient, 1)[:, 0]
    wrist = None
    if hand.transl is not None and rig is not None:
        wrist = mano_wrist(rig, hand.betas, hand.transl, fix_left_shapedirs=hand.fix_left_shapedirs)
    if hand.mirrored:
        fingers = mirror_axis_angle(fingers)
        orient = mirror_matrix(orient)
        wrist = None if wrist is None else wrist @ MIRROR
    cam = check_camera_rotation(hand.camera_rotation, label)
    if cam is not None:
        orient = np.swapaxes(cam, -1, -2) @ orient
        if wrist is not None:
            t = np.zeros(3) if hand.camera_translation is None else np.asarray(hand.camera_translation, np.float64)
            wrist = np.einsum("...ji,...j->...i", cam, wrist - t)
    batch = max(orient.shape[0], fingers.shape[0])
    orient = np.broadcast_to(orient, (batch, 3, 3))
    fingers = np.broadcast_to(fingers, (batch, 45))
    return HandRotations(orient, fingers, wrist)


def mano_wrist(rig: RigFacts, betas: Any, transl: Any, *, fix_left_shapedirs: bool = True) -> np.ndarray:
    """(B, 3) MANO's root joint (the wrist) for ``betas`` and ``transl``: it does not move with the pose.

    For a left model with ``fix_left_shapedirs``, the x row of the shape basis is negated (see
    :func:`left_shapedirs_flipped`).
    """
    joint = rig.template_joints[0]
    offset = np.zeros((1, 3))
    if betas is not None:
        b = np.atleast_2d(np.asarray(betas, dtype=np.float64))[:, : rig.joint_shapedirs.shape[-1]]
        dirs = rig.joint_shapedirs[0, :, : b.shape[1]]
        if fix_left_shapedirs and rig.side == "left":
            dirs = dirs * np.array([-1.0, 1.0, 1.0])[:, None]
        offset = b @ dirs.T
    return joint + offset + np.atleast_2d(np.asarray(transl, dtype=np.float64))


def left_shapedirs_flipped(left_model: Any, right_model: Any) -> bool:
    """Whether ``left_model``'s shape basis has the official ``MANO_LEFT.pkl`` defect.

    The left hand is the mirror (x -> -x) of the right one, so a correct left ``shapedirs[:, 0, :]`` (the x
    displacements) is the right one's negated; the official file has it with the right hand's sign, so the
    same ``betas`` give the two hands different shapes (smplx#48; the fix used by HaMeR, DexYCB and others:
    ``shapedirs[:, 0, :] *= -1`` for the left model). True when the x rows agree in sign with the right
    model's (closer to them than to their negation).
    """
    left, right = _rig_of(left_model), _rig_of(right_model)
    if (left.model_type, left.side, right.model_type, right.side) != ("mano", "left", "mano", "right"):
        raise ValueError("left_model, right_model: expected a left and a right MANO model")
    k = min(left.shapedirs.shape[-1], right.shapedirs.shape[-1])
    lx, rx = left.shapedirs[:, 0, :k], right.shapedirs[:, 0, :k]
    return bool(np.abs(lx - rx).sum() < np.abs(lx + rx).sum())


def fixed_left_shapedirs(left_model: Any) -> np.ndarray:
    """(V, 3, S) the left MANO model's shape basis with its x rows negated (the MANO_LEFT.pkl fix)."""
    rig = _rig_of(left_model)
    if (rig.model_type, rig.side) != ("mano", "left"):
        raise ValueError(f"left_model: expected a left MANO model, got {rig.model_type} ({rig.side})")
    return rig.shapedirs * np.array([-1.0, 1.0, 1.0])[None, :, None]
