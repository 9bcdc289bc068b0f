"""What the rigged exporters (glTF, BVH) share: model input turned into a skeleton animation.

:func:`prepare_animation` takes a model and any supported input -- a :class:`~smplcore.motion.Motion`,
the path of an AMASS-style ``.npz`` (or of a parameter-set ``.npz`` / ``.json``), a dict of model
keyword arrays (one parameter set or a batch of frames) -- and returns an :class:`Animation`: the
shaped rest pose (vertices and joints), per-frame local joint rotations (T, J, 3, 3) and the root
translation. Both writers start from it, so they agree with each other and with the model.

Rest-pose semantics (what a rig made from this reproduces):

* rest mesh = the template with the body shape (``betas``) applied, unposed;
* joint rest transforms = translation by ``joint - parent joint``, identity rotation (SMPL's frame);
* skinning = the model's linear blend skinning *without* pose-corrective blend shapes -- a rig has no
  way to express those; :func:`pose_corrective_error` measures what is lost for models that have them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.export.soft_tissue import dmpls_of

__all__ = [
    "Animation",
    "ExportReport",
    "load_input",
    "prepare_animation",
    "top_k_weights",
    "truncation_error",
    "pose_corrective_error",
    "lbs",
]

Progress = Callable[[int], Any]  # called with the number of frames just processed (e.g. tqdm.update)

# the input readers live in inputs and the skinning helpers in skin_metrics (re-exported here, where
# exporters import them)
from smplcore.export.inputs import (  # noqa: E402
    _fit_width,
    _frames_of,
    _motion_input,
    _notify,
    _single_shape,
    fit_result_params,
    load_input,
)
from smplcore.export.skin_metrics import (  # noqa: E402,F401
    FRAMES_PER_CHUNK,
    lbs,
    pose_corrective_error,
    top_k_weights,
    truncation_error,
)

DEFAULT_FPS = 30.0
_CHUNK = FRAMES_PER_CHUNK


@dataclass
class Animation:
    """A skeleton animation of one shaped body.

    Attributes
    ----------
    rotations : (T, J, 3, 3) float64 local joint rotations (the root's is the global orientation).
    transl : (T, 3) root translation (metres) added on top of the rest root joint.
    rest_joints : (J, 3) shaped, unposed joint positions.
    rest_vertices : (V, 3) shaped, unposed vertices (with ``base_expression`` applied).
    faces : (F, 3) triangles.
    weights : (V, J) full skinning weights.
    parents : (J,) parent of each joint (-1 for the root).
    joint_names : the J skeleton joint names.
    fps : frame rate.
    betas : (S,) the shape coefficients as used (matching the model's ``num_betas``).
    expression : (T, E) per-frame expression coefficients, or None for models without expressions.
    base_expression : (E,) the expression baked into ``rest_vertices`` (the constant expression, or zeros).
    dmpls : (T, n) per-frame DMPL soft-tissue coefficients (a model with ``dmpl_path`` and an input that
        has them), else None; ``rest_vertices`` and ``rest_joints`` are without soft tissue.
    model_type : the model's type.
    source : where the input came from.
    notes : warnings raised while preparing (also issued with :func:`warnings.warn`).
    """

    rotations: np.ndarray
    transl: np.ndarray
    rest_joints: np.ndarray
    rest_vertices: np.ndarray
    faces: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    joint_names: list[str]
    fps: float
    betas: np.ndarray
    expression: np.ndarray | None = None
    base_expression: np.ndarray | None = None
    dmpls: np.ndarray | None = None
    model_type: str = ""
    source: str = "<memory>"
    notes: list[str] = field(default_factory=list)

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def num_joints(self) -> int:
        return int(self.rotations.shape[1])

    @property
    def root_positions(self) -> np.ndarray:
        """(T, 3) world position of the root joint: rest root joint + translation."""
        return self.rest_joints[0] + self.transl

    @property
    def offsets(self) -> np.ndarray:
        """(J, 3) rest offset of each joint from its parent (the root's from the origin)."""
        out = self.rest_joints.copy()
        out[1:] -= self.rest_joints[self.parents[1:]]
        return out

    @property
    def expression_varies(self) -> bool:
        return (
            self.expression is not None
            and self.expression.shape[0] > 0
            and bool(np.any(np.abs(self.expression - self.base_expression) > 0))
        )

    def world_transforms(self, frames: slice | np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (T', J, 3, 3) and positions (T', J, 3) of the joints (translation included)."""
        from smplcore.engine import KinematicTree, world_transforms

        rot = self.rotations if frames is None else self.rotations[frames]
        transl = self.transl if frames is None else self.transl[frames]
        rest = np.broadcast_to(self.rest_joints, rot.shape[:2] + (3,))
        world_rot, world_pos = world_transforms(rot, rest, KinematicTree.from_parents(self.parents))
        return world_rot, world_pos + transl[:, None]

    def joints(self, frames: slice | np.ndarray | None = None) -> np.ndarray:
        """(T', J, 3) posed joint positions."""
        return self.world_transforms(frames)[1]

    def skinning_matrices(self, frames: slice | np.ndarray | None = None) -> np.ndarray:
        """(T', J, 3, 4) transforms taking a rest-pose point near joint j to its posed position."""
        from smplcore.engine import skinning_transforms

        world_rot, world_pos = self.world_transforms(frames)
        rest = np.broadcast_to(self.rest_joints, world_pos.shape)
        flat = skinning_transforms(world_rot, world_pos, rest)  # (T', J, 12): rotation rows, translation
        return np.concatenate([flat[..., :9].reshape(world_rot.shape), flat[..., 9:, None]], axis=-1)


@dataclass
class ExportReport:
    """What an exporter wrote and what the format could not carry.

    Distances are in metres. ``top4_*`` compare the written skin (top ``influences`` weights per
    vertex, renormalised) with full-weight linear blend skinning over every exported frame: the max
    and mean displacement over all vertices and frames, and how many vertices lost weight.
    ``pose_corrective_max`` is the largest vertex displacement of the model's pose correctives over
    the exported frames (None for models without them) -- a rig cannot reproduce it.
    ``engine``, ``unit_scale`` and ``ground_lift`` (metres, before scaling) describe a glTF written for a
    game engine (:func:`smplcore.export.save_glb` with ``engine=``); the distances above stay in metres.
    """

    path: Path
    format: str
    num_frames: int
    fps: float
    num_joints: int
    num_vertices: int = 0
    file_size: int = 0
    influences: int | None = None
    max_model_influences: int | None = None
    top4_max_error: float | None = None
    top4_mean_error: float | None = None
    top4_vertices_affected: int | None = None
    top4_max_dropped_weight: float | None = None
    pose_corrective_max: float | None = None
    morph_targets: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    engine: str | None = None
    unit_scale: float = 1.0
    ground_lift: float | None = None

    def summary(self) -> str:
        """A few human-readable lines."""
        size = self.file_size
        human = f"{size / 1e6:.2f} MB" if size >= 1e6 else f"{size / 1e3:.1f} kB"
        what = f"{self.num_frames} frame(s) at {self.fps:g} fps" if self.num_frames else "the rest pose"
        lines = [
            f"wrote {self.path} ({self.format}, {human}): {what}, "
            f"{self.num_joints} joints" + (f", {self.num_vertices} vertices" if self.num_vertices else "")
        ]
        if self.top4_max_error is not None and self.top4_mean_error is not None:
            lines.append(
                f"skin: top {self.influences} of up to {self.max_model_influences} weights per vertex, "
                "renormalised; "
                f"{self.top4_vertices_affected} vertices truncated (max dropped weight "
                f"{self.top4_max_dropped_weight:.4f}); vertex error vs full skinning: max "
                f"{self.top4_max_error * 1000:.3f} mm, mean {self.top4_mean_error * 1000:.4f} mm"
            )
        if self.engine is not None:
            lines.append(
                f"engine: {self.engine} (root bone 'root', lengths x{self.unit_scale:g}, lifted "
                f"{(self.ground_lift or 0.0) * 1000:+.1f} mm so the lowest vertex touches y = 0)"
            )
        if self.morph_targets:
            lines.append(
                f"morph targets: {len(self.morph_targets)} ({', '.join(self.morph_targets[:4])}"
                f"{', ...' if len(self.morph_targets) > 4 else ''})"
            )
        if self.pose_corrective_max is not None:
            lines.append(
                f"pose correctives not exported (a rig cannot express them): up to "
                f"{self.pose_corrective_max * 1000:.1f} mm per vertex"
            )
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def prepare_animation(
    model: Any, source: Any, *, fps: float | None = None, progress: Progress | None = None
) -> Animation:
    """Turn ``source`` into an :class:`Animation` of ``model`` (a :class:`smplcore.BodyModel`).

    Parameters
    ----------
    model : the body model; its ``num_betas`` decides how many shape coefficients are used (more in the
        input are dropped with a warning, fewer are padded with zeros).
    source : a :class:`~smplcore.motion.Motion`; a path (see :func:`load_input`); a dict with ``poses``
        (and ``trans``, ``betas``, ``mocap_framerate``: AMASS arrays); or a dict of model keyword arguments
        (``betas``, ``expression``, ``transl`` and pose blocks such as ``global_orient``/``body_pose``),
        each (n,) / (1, n) for one frame or (T, n) for T frames. Parameter sets go through the model, so
        PCA hands and the model's mean hand pose apply as in ``model(**params)``. Motion poses are full
        axis-angle poses, hands included (never PCA), plus the model's mean hand pose -- AMASS hand poses
        are absolute, so create the model with ``flat_hand_mean=True`` for them.
    fps : frame rate; overrides the motion's (default: the motion's, or 30 for parameter sets). A motion
        that states no frame rate needs it (:class:`~smplcore.errors.ModelFileError` otherwise).
    progress : called with the number of frames processed, e.g. ``tqdm(total=T).update``.
    """
    from smplcore.motion import Motion

    notes: list[str] = []
    if isinstance(source, (str, Path)):
        source = load_input(source, fps=fps)
    source = fit_result_params(source)  # a FitResult: its parameters, as NumPy arrays
    if isinstance(source, Mapping) and "poses" in source:
        source = _motion_input(source, fps=fps)
    if isinstance(source, Motion):
        rotations, transl, betas, expression, rate, origin = _from_motion(model, source, notes, progress)
    elif isinstance(source, Mapping):
        rotations, transl, betas, expression, origin = _from_params(model, source, notes, progress)
        rate = next(
            (
                float(np.asarray(source[k]).reshape(-1)[0])
                for k in ("fps", "mocap_framerate", "mocap_frame_rate")
                if k in source
            ),
            DEFAULT_FPS,
        )
    else:
        raise TypeError(f"source: expected a Motion, a path or a dict of parameter arrays, got {type(source).__name__}")
    if fps is not None:
        rate = float(fps)
    if not (np.isfinite(rate) and rate > 0):
        raise ValueError(f"fps: expected a positive frame rate, got {rate}")

    base_expression = None
    if expression is not None:
        constant = np.allclose(expression, expression[:1], rtol=0, atol=0)
        base_expression = expression[0].copy() if constant else np.zeros(expression.shape[1])
    rest_vertices, rest_joints = model.rest_pose(betas, base_expression)
    rest_vertices = np.asarray(rest_vertices, dtype=np.float64)
    rest_joints = np.asarray(rest_joints, dtype=np.float64)
    dmpls = dmpls_of(model, source, rotations.shape[0])
    if expression is not None and base_expression is not None and not constant:
        joint_dirs = model.rig.joint_exprdirs  # (J, 3, E)
        moved = np.einsum("tk,jdk->tjd", expression - base_expression, joint_dirs)
        shift = float(np.linalg.norm(moved, axis=-1).max())
        if shift > 1e-6:
            notes.append(
                f"expression moves the model's rest joints by up to {shift * 1000:.2f} mm; the exported "
                "skeleton uses the joints of the neutral expression"
            )
    return Animation(
        rotations=rotations,
        transl=transl,
        rest_joints=rest_joints,
        rest_vertices=rest_vertices,
        faces=np.asarray(model.faces),
        weights=np.asarray(model.skinning_weights, dtype=np.float64),
        parents=np.asarray(model.parents),
        joint_names=list(model.skeleton_joint_names),
        fps=rate,
        betas=betas,
        expression=expression,
        base_expression=base_expression,
        dmpls=dmpls,
        model_type=model.model_type,
        source=origin,
        notes=notes,
    )


def _from_motion(model: Any, motion: Any, notes: list[str], progress: Progress | None):
    from smplcore.engine.rotations import rodrigues

    names = list(model.skeleton_joint_names)
    source_names = _joint_names_of(motion.model_type)
    if not set(names) & set(source_names):
        raise ValueError(f"the {motion.model_type} motion shares no joints with the {model.model_type} model")
    params = motion.model_params(model.model_type, names, model.num_betas)
    frames = motion.num_frames
    full = np.concatenate([np.asarray(params[b], np.float64).reshape(frames, -1) for b in model.pose_blocks], axis=1)
    full = full + model.rig.pose_mean  # zeros unless the hand mean is not flat
    rotations = np.empty((frames, len(names), 3, 3))
    for start in range(0, frames, _CHUNK):
        stop = min(start + _CHUNK, frames)
        rotations[start:stop] = rodrigues(full[start:stop].reshape(stop - start, -1, 3))
        if progress is not None:
            progress(stop - start)
    betas = _fit_width("betas", np.asarray(motion.betas, np.float64).reshape(-1), model.num_betas, notes)
    expression = None
    if model.num_expression_coeffs:
        expr = params.get("expression")
        expression = (
            np.zeros((frames, model.num_expression_coeffs))
            if expr is None
            else _fit_width("expression", np.asarray(expr, np.float64), model.num_expression_coeffs, notes)
        )
    return rotations, np.asarray(motion.trans, np.float64), betas, expression, motion.fps, motion.source


def _joint_names_of(model_type: str) -> list[str]:
    from smplcore.family.specs import get_spec

    return list(get_spec(model_type).joint_names)


def _from_params(model: Any, source: Mapping[str, Any], notes: list[str], progress: Progress | None):
    allowed = set(model.pose_blocks) | {"betas", "expression", "transl"}
    allowed |= {"dmpls"} if getattr(model, "num_dmpls", 0) else set()
    meta = {"fps", "mocap_framerate", "mocap_frame_rate", "gender", "model_type", "surface_model_type"}
    unknown = sorted(set(source) - allowed - meta)
    if unknown:
        _notify(notes, f"ignoring parameter(s) {unknown}: a {model.model_type} model takes {sorted(allowed)}")
    params = {k: np.asarray(v, dtype=np.float64) for k, v in source.items() if k in allowed and v is not None}
    for k, v in params.items():
        if v.ndim == 1 or v.ndim == 0:
            params[k] = v.reshape(1, -1)
    betas = _single_shape("betas", params.pop("betas", np.zeros(model.num_betas)), model.num_betas, notes)
    expression = None
    if model.num_expression_coeffs:
        expr = params.pop("expression", None)
        if expr is not None:
            expression = _fit_width("expression", expr.reshape(expr.shape[0], -1), model.num_expression_coeffs, notes)
    else:
        params.pop("expression", None)
    frames = _frames_of({**params, **({} if expression is None else {"expression": expression})})
    params.pop("dmpls", None)  # soft tissue does not move the skeleton's rotations (read by dmpls_of)
    transl = params.pop("transl", np.zeros((1, 3))).reshape(-1, 3)
    if transl.shape[0] not in (1, frames):
        raise ShapeError(f"transl: expected shape ({frames}, 3) or (1, 3), got {transl.shape}")
    transl = np.broadcast_to(transl, (frames, 3)).copy()
    if expression is not None:
        expression = np.broadcast_to(expression, (frames, expression.shape[1])).copy()
    rotations = np.empty((frames, len(model.skeleton_joint_names), 3, 3))
    for start in range(0, frames, _CHUNK):
        stop = min(start + _CHUNK, frames)
        chunk = {k: (v[start:stop] if v.shape[0] == frames and frames > 1 else v) for k, v in params.items()}
        out = model(betas=betas[None], return_verts=False, **chunk)
        rot = np.asarray(out.rotmats, dtype=np.float64)
        rotations[start:stop] = np.broadcast_to(rot, (stop - start,) + rot.shape[1:])
        if progress is not None:
            progress(stop - start)
    if expression is None and model.num_expression_coeffs:
        expression = np.zeros((frames, model.num_expression_coeffs))
    return rotations, transl, betas, expression, "<parameters>"
