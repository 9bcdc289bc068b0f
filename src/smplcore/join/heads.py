"""FLAME heads onto SMPL-X bodies (:func:`join_head`) and back (:func:`split_head`).

Poses: FLAME's root and neck are SMPL-X's neck and head joints; FLAME's head orientation (``global_orient``
then ``neck_pose``) becomes the world rotation of SMPL-X's ``head`` joint through the chain
(``head_local = neck_worldᵀ · flame_head_world``); the jaw and eyes are local rotations of the same joints in
both models and carry over as they are. Shapes do not transfer (SMPL-X was retrained: its head shape space is
not FLAME's). Expressions transfer directly where the two bases agree on the head's vertices, else through
the linear least-squares map between them (:class:`ExpressionMap`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.join._rig import RigFacts, _rig_of
from smplcore.join.body import (
    copy_params,
    joint_positions,
    local_rotations,
    rotations_as_axis_angle,
    set_joint,
    world_rotations,
)
from smplcore.join.hands import JoinResult
from smplcore.join.mano import check_camera_rotation
from smplcore.join.rotations import angle_between, as_rotations, numpy_of, to_axis_angle

#: FLAME's keywords that are rotations of one joint each.
_FLAME_POSES = ("global_orient", "neck_pose", "jaw_pose", "leye_pose", "reye_pose")
#: The body's joints that FLAME's jaw and eyes are (SMPL-X names).
_FACE_JOINTS = {"jaw_pose": "jaw", "leye_pose": "left_eye_smplhf", "reye_pose": "right_eye_smplhf"}
#: Bases whose relative difference on the shared vertices is at most this agree (float32 files: ~1e-7).
AGREE_TOLERANCE = 1e-4


@dataclass
class FlameHead:
    """FLAME parameters of a head.

    Attributes
    ----------
    global_orient, neck_pose, jaw_pose, leye_pose, reye_pose : (B, 3) axis-angle or (B, 3, 3) matrices (None:
        zero). ``global_orient`` is in the world frame, or the camera frame with ``camera_rotation``.
    expression : (B, E) FLAME expression coefficients, or None.
    betas, transl : FLAME shape and translation, carried along (shapes do not transfer to SMPL-X).
    camera_rotation : (3, 3) or (B, 3, 3) world-to-camera rotation when ``global_orient`` is in a camera frame.
    """

    global_orient: Any = None
    neck_pose: Any = None
    jaw_pose: Any = None
    leye_pose: Any = None
    reye_pose: Any = None
    expression: Any = None
    betas: Any = None
    transl: Any = None
    camera_rotation: Any = None


@dataclass(frozen=True)
class ExpressionMap:
    """The linear map from one model's expression coefficients to another's, on shared head vertices.

    ``matrix`` (E_to, E_from): ``e_to = e_from @ matrix.T``; ``direct``: the bases agree and the map copies
    coefficients (identity, cut or zero-padded); ``difference``: relative difference of the two bases on the
    shared vertices (their first ``min(E)`` components; NaN when not measured).
    """

    matrix: np.ndarray
    direct: bool
    difference: float

    def __call__(self, expression: np.ndarray) -> np.ndarray:
        return np.atleast_2d(np.asarray(expression, dtype=np.float64)) @ self.matrix.T


@dataclass(frozen=True)
class HeadResidual:
    """How well the body's head reproduces the given one (arrays of shape (B,)).

    ``head_angle``: angle between the body's head-joint world orientation and FLAME's head orientation;
    ``face_angle``: largest angle over jaw and eyes; ``expression_rms``: RMS distance (metres) over the shared
    vertices between the body's expression displacement and FLAME's (NaN without a vertex correspondence);
    ``direct``: the expression was copied (the bases agree).
    """

    head_angle: np.ndarray
    face_angle: np.ndarray
    expression_rms: np.ndarray
    direct: bool

    @property
    def max_angle(self) -> float:
        return float(max(np.max(self.head_angle), np.max(self.face_angle)))


def _smplx_rig(body_model: Any) -> RigFacts:
    rig = _rig_of(body_model)
    if rig.model_type != "smplx":
        raise ValueError(f"body_model: expected an SMPL-X model (with a face), got a {rig.model_type} model")
    return rig


def _flame_rig(flame_model: Any) -> RigFacts:
    rig = _rig_of(flame_model)
    if rig.model_type != "flame":
        raise ValueError(f"flame_model: expected a FLAME model, got a {rig.model_type} model")
    return rig


def _vertex_ids(vertex_ids: Any, body: RigFacts, flame: RigFacts) -> np.ndarray:
    ids = np.asarray(vertex_ids)
    if ids.shape != (len(flame.template),) or ids.dtype.kind not in "iu":
        raise ShapeError(
            f"vertex_ids: expected ({len(flame.template)},) integer indices of the body's vertices (one per FLAME "
            f"vertex, as SMPL-X__FLAME_vertex_ids.npy), got {ids.shape} {ids.dtype}"
        )
    if ids.min() < 0 or ids.max() >= len(body.template):
        raise ValueError(f"vertex_ids: expected indices in [0, {len(body.template)}), got {ids.min()}..{ids.max()}")
    return ids.astype(np.int64)


def expression_map(
    from_model: Any, to_model: Any, vertex_ids: Any = None, *, mode: str = "auto", tolerance: float = AGREE_TOLERANCE
) -> ExpressionMap:
    """The map from ``from_model``'s expression coefficients to ``to_model``'s (FLAME <-> SMPL-X).

    Parameters
    ----------
    from_model, to_model : a FLAME and an SMPL-X model (either way round), with their
        ``num_expression_coeffs`` options.
    vertex_ids : (V_flame,) the SMPL-X vertex of each FLAME vertex (the official ``SMPL-X__FLAME_vertex_ids.npy``).
    mode : ``"auto"`` (copy when the bases agree within ``tolerance`` on the shared vertices, else fit; needs
        ``vertex_ids``), ``"direct"`` (copy: the FLAME 2020 / SMPL-X 2020 authors say the expression spaces
        coincide, smplx#51, smplx#122) or ``"fit"`` (least squares on the shared vertices; needs ``vertex_ids``).
    tolerance : largest relative difference of the bases that still counts as agreeing.
    """
    if mode not in ("auto", "direct", "fit"):
        raise ValueError(f"mode: expected 'auto', 'direct' or 'fit', got {mode!r}")
    a, b = _rig_of(from_model), _rig_of(to_model)
    kinds = {a.model_type, b.model_type}
    if kinds != {"flame", "smplx"}:
        raise ValueError(f"from_model, to_model: expected a FLAME and an SMPL-X model, got {sorted(kinds)}")
    ea, eb = a.exprdirs.shape[-1], b.exprdirs.shape[-1]
    if vertex_ids is None:
        if mode != "direct":
            raise ValueError(
                f"vertex_ids: mode={mode!r} needs the SMPL-X vertex of each FLAME vertex "
                "(SMPL-X__FLAME_vertex_ids.npy); or pass mode='direct' to copy the coefficients"
            )
        return ExpressionMap(np.eye(eb, ea), True, float("nan"))
    flame, body = (a, b) if a.model_type == "flame" else (b, a)
    ids = _vertex_ids(vertex_ids, body, flame)
    basis_a = (a.exprdirs if a is flame else a.exprdirs[ids]).reshape(-1, ea)
    basis_b = (b.exprdirs if b is flame else b.exprdirs[ids]).reshape(-1, eb)
    k = min(ea, eb)
    scale = max(float(np.linalg.norm(basis_a[:, :k])), 1e-300)
    difference = float(np.linalg.norm(basis_a[:, :k] - basis_b[:, :k]) / scale)
    if mode == "direct" or (mode == "auto" and difference <= tolerance):
        return ExpressionMap(np.eye(eb, ea), True, difference)
    return ExpressionMap(np.linalg.lstsq(basis_b, basis_a, rcond=None)[0], False, difference)


def _rotations(head: FlameHead, name: str, batch: int) -> np.ndarray:
    value = getattr(head, name)
    if value is None:
        return np.broadcast_to(np.eye(3), (batch, 3, 3))
    return np.broadcast_to(as_rotations(f"head.{name}", value, 1)[:, 0], (batch, 3, 3))


def _head_batch(head: FlameHead) -> int:
    """The batch size of ``head``'s batched (2-D or more) parameters (1 if none), checked to agree."""
    values = [getattr(head, n) for n in (*_FLAME_POSES, "expression")]
    sizes = {int(np.shape(v)[0]) for v in values if v is not None and np.ndim(v) >= 2} - {1}
    if len(sizes) > 1:
        raise ShapeError(f"head: batch sizes {sorted(sizes)} do not broadcast")
    return sizes.pop() if sizes else 1


def join_head(
    body_model: Any,
    body_params: dict[str, Any],
    head: FlameHead | dict,
    flame_model: Any = None,
    *,
    vertex_ids: Any = None,
    expression: str = "auto",
) -> JoinResult:
    """Put a FLAME head on an SMPL-X body: its head joint, jaw, eyes and expression.

    Parameters
    ----------
    body_model, body_params : the SMPL-X body and its keywords (not modified).
    head : :class:`FlameHead` (or a dict of its fields).
    flame_model : the FLAME model of ``head`` (its expression basis); needed unless ``expression="direct"``
        or the head has no expression.
    vertex_ids, expression : the vertex correspondence and the mode of :func:`expression_map`.

    Returns
    -------
    :class:`JoinResult` with ``params`` (``body_pose`` with the head joint set, ``jaw_pose``, ``leye_pose``,
    ``reye_pose``, ``expression`` (B, the body's ``num_expression_coeffs``)) and ``residuals["head"]``, a
    :class:`HeadResidual`.
    """
    rig = _smplx_rig(body_model)
    if isinstance(head, dict):
        head = FlameHead(**head)
    if not isinstance(head, FlameHead):
        raise TypeError(f"head: expected a FlameHead or a dict of its fields, got {type(head).__name__}")
    head = replace(head, **{f.name: numpy_of(getattr(head, f.name)) for f in fields(head)})
    params, batch = copy_params(body_params, (_head_batch(head),))
    rotations_as_axis_angle(rig, params, batch)
    flame_head = _rotations(head, "global_orient", batch) @ _rotations(head, "neck_pose", batch)
    cam = check_camera_rotation(head.camera_rotation, "head")
    if cam is not None:
        flame_head = np.swapaxes(cam, -1, -2) @ flame_head
    world = world_rotations(rig, local_rotations(rig, params, batch))
    joint = rig.joint_names.index("head")
    set_joint(rig, params, joint, np.swapaxes(world[:, rig.parents[joint]], -1, -2) @ flame_head, batch)
    for name in _FACE_JOINTS:
        params[name] = to_axis_angle(_rotations(head, name, batch))
    rms = np.full(batch, np.nan)
    direct = True
    if head.expression is not None:
        if flame_model is None and expression != "direct":
            raise ValueError("flame_model: mapping FLAME's expression needs the FLAME model (or expression='direct')")
        flame_expr = np.atleast_2d(np.asarray(head.expression, dtype=np.float64))
        if flame_model is None:
            mapping = ExpressionMap(np.eye(rig.num_expression_coeffs, flame_expr.shape[1]), True, float("nan"))
        else:
            flame = _flame_rig(flame_model)
            if flame_expr.shape[1] != flame.num_expression_coeffs:
                raise ShapeError(
                    f"head.expression: expected (B, {flame.num_expression_coeffs}) (the FLAME model's "
                    f"num_expression_coeffs), got {flame_expr.shape}"
                )
            mapping = expression_map(flame_model, body_model, vertex_ids, mode=expression)
            if vertex_ids is not None:
                ids = _vertex_ids(vertex_ids, rig, flame)
                target = np.einsum("vck,bk->bvc", flame.exprdirs, flame_expr)
                got = np.einsum("vck,bk->bvc", rig.exprdirs[ids], mapping(flame_expr))
                rms = np.sqrt(np.mean(np.sum((got - target) ** 2, axis=-1), axis=-1))
        params["expression"] = np.broadcast_to(mapping(flame_expr), (batch, rig.num_expression_coeffs)).copy()
        direct = mapping.direct
    world = world_rotations(rig, local_rotations(rig, params, batch))
    face = [rig.joint_names.index(n) for n in _FACE_JOINTS.values()]
    local = local_rotations(rig, params, batch)
    given = np.stack([_rotations(head, n, batch) for n in _FACE_JOINTS], axis=1)
    residual = HeadResidual(
        head_angle=angle_between(world[:, joint], flame_head),
        face_angle=angle_between(local[:, face], given).max(axis=1),
        expression_rms=np.broadcast_to(rms, (batch,)).copy(),
        direct=direct,
    )
    return JoinResult(params, {"head": residual})


def split_head(
    body_model: Any,
    body_params: dict[str, Any],
    flame_model: Any = None,
    *,
    vertex_ids: Any = None,
    expression: str = "auto",
    camera_rotation: Any = None,
    camera_translation: Any = None,
) -> FlameHead:
    """An SMPL-X body's head as FLAME parameters (the inverse of :func:`join_head`).

    ``global_orient`` is the world rotation of SMPL-X's neck joint (FLAME's root), in the camera frame with
    ``camera_rotation`` (and ``camera_translation``, world to camera); ``neck_pose`` the head joint's local
    rotation; ``jaw_pose`` / ``leye_pose`` / ``reye_pose`` as they are; ``expression`` mapped with
    :func:`expression_map` (``flame_model`` and ``vertex_ids`` as there), or None when the body has none.
    With ``flame_model``, ``transl`` puts FLAME's root joint on SMPL-X's neck joint (zero FLAME ``betas``:
    shape does not transfer).
    """
    rig = _smplx_rig(body_model)
    params, batch = copy_params(body_params)
    local = local_rotations(rig, params, batch)
    world = world_rotations(rig, local)
    head_joint = rig.joint_names.index("head")
    neck = int(rig.parents[head_joint])
    root = world[:, neck]
    position = joint_positions(rig, params, world)[:, neck] if flame_model is not None else None
    cam = check_camera_rotation(camera_rotation, "split_head")
    if cam is not None:
        root = cam @ root
        if position is not None:
            t = np.zeros(3) if camera_translation is None else numpy_of(camera_translation)
            position = np.einsum("...ij,...j->...i", cam, position) + t
    out = FlameHead(
        global_orient=to_axis_angle(root),
        neck_pose=to_axis_angle(local[:, head_joint]),
        camera_rotation=cam,
    )
    if position is not None:
        flame = _flame_rig(flame_model)
        out.transl = position - flame.template_joints[0]
        out.betas = np.zeros((batch, flame.num_betas))
    for name, joint in _FACE_JOINTS.items():
        setattr(out, name, to_axis_angle(local[:, rig.joint_names.index(joint)]))
    body_expr = params.get("expression")
    if body_expr is not None:
        if flame_model is None:
            if expression != "direct":
                raise ValueError("flame_model: mapping the expression needs the FLAME model (or expression='direct')")
            out.expression = np.atleast_2d(body_expr).copy()
        else:
            _flame_rig(flame_model)
            out.expression = expression_map(body_model, flame_model, vertex_ids, mode=expression)(body_expr)
    return out
