"""Rigged, animated bodies as FBX 7.4 binary (``.fbx``), for Blender, Unity, Unreal, Maya, MotionBuilder.

The file holds

* a mesh (``Geometry`` + ``Model``): the shaped rest mesh (betas applied), polygon indices (each face's last
  index stored as ``-(i + 1)``), smooth per-vertex normals, and the model's UV map when it has one
  (``LayerElementUV``, one UV per face corner, so nothing is split along the seams); optionally vertex colours
  (``LayerElementColor``) and a diffuse texture embedded as PNG (``Video`` + ``Texture`` on the material);
* a skeleton: one ``LimbNode`` model per joint, named after it, nested as the kinematic tree, rest
  transforms ``joint - parent joint`` with no rotation; optionally a ``root`` bone at the origin above the
  pelvis (what Unreal's importer expects); the rest pose is the bind pose (a ``BindPose`` node);
* a skin: one ``Cluster`` per joint holding every non-zero weight of the model (no top-4 truncation),
  ``TransformLink`` = the joint's rest transform, ``Transform`` = its inverse;
* blend shapes (``BlendShape`` > ``BlendShapeChannel`` > ``Shape``) as vertex offsets: the shape
  coefficients (``beta_0`` ...; at 0, the shape is baked into the mesh) and expressions (``expr_0`` ...,
  animated) with ``shape_keys=True``; the pose correctives with ``pose_correctives=True`` (``pose_<joint>_<rc>``:
  one key per entry of ``R - I`` of each joint, weights animated from the motion, so skinning the keyed
  mesh reproduces the full model); DMPL soft tissue (``dmpl_0`` ..., animated) whenever the input has it;
* one animation stack: Euler rotation curves (degrees, ``rotation_order``, continuous over time) for
  every joint and translation curves for the pelvis, keyed at ``k / fps`` with linear interpolation;
* ``GlobalSettings``: centimetres (``unit="cm"``: values in cm, ``UnitScaleFactor`` 1, FBX's native unit and
  Unreal's) or metres (``unit="m"``: values in m, ``UnitScaleFactor`` 100), and Y up (SMPL's frame, facing
  +Z; Unity, Maya) or Z up (``up_axis="z"``: the data rotated +90 degrees about X, facing -Y; Blender,
  Unreal, 3ds Max). Importers convert from either to their own frame.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import warn
from smplcore.export.animation import Animation, ExportReport, Progress, pose_corrective_error, prepare_animation
from smplcore.export.bvh import euler_angles
from smplcore.export.fbx.binary import write_file
from smplcore.export.fbx.document import Document, ktime
from smplcore.export.fbx.objects import (
    Shape,
    add_animation_stack,
    add_blend_shapes,
    add_curves,
    add_mesh,
    add_skeleton,
    add_skin,
    add_texture,
)
from smplcore.export.gltf import _version, _vertex_normals
from smplcore.export.mesh import _check_vertex_colors
from smplcore.export.soft_tissue import dmpl_joint_shift
from smplcore.uv import TextureInput, encode_png, resolve_texture

__all__ = ["save_fbx", "ROTATION_ORDERS"]

#: FBX's RotationOrder enum; "XYZ" = rotate about X first, then Y, then Z (matrix Rz @ Ry @ Rx)
ROTATION_ORDERS = {"XYZ": 0, "XZY": 1, "YZX": 2, "YXZ": 3, "ZXY": 4, "ZYX": 5}
_UNITS = {"cm": (100.0, 1.0), "m": (1.0, 100.0)}  # values per metre, UnitScaleFactor (cm per unit)
_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # +90 degrees about X: y -> z


def _euler_xyz(rotations: np.ndarray, order: str) -> np.ndarray:
    """(T, J, 3, 3) -> (T, J, 3) angles about X, Y, Z (degrees) for FBX ``order`` (first axis applied first)."""
    intrinsic = euler_angles(rotations, order[::-1])  # R = R_c @ R_b @ R_a for FBX order "abc"
    out = np.empty_like(intrinsic)
    for k, axis in enumerate(order[::-1]):
        out[..., "XYZ".index(axis)] = intrinsic[..., k]
    return out


def save_fbx(
    path: str | Path,
    model: Any,
    source: Any,
    *,
    fps: float | None = None,
    unit: str = "cm",
    up_axis: str = "y",
    input_up_axis: str = "y",
    root_bone: str | None = None,
    shape_keys: bool = False,
    pose_correctives: bool = False,
    uv: bool | None = None,
    vertex_colors: Any = None,
    texture: TextureInput | None = None,
    rotation_order: str = "XYZ",
    name: str | None = None,
    progress: Progress | None = None,
) -> ExportReport:
    """Write ``source`` on ``model`` as a rigged, animated FBX 7.4 binary file.

    Parameters
    ----------
    path : the ``.fbx`` to write (parent folders are created).
    model : a :class:`smplcore.BodyModel`.
    source : a :class:`~smplcore.motion.Motion`, a motion or parameter file, a dict of parameter arrays (one
        set or T frames), or an :class:`~smplcore.export.animation.Animation`.
    fps : frame rate (default: the motion's, 30 for parameter sets).
    unit : ``"cm"`` (default: values in centimetres, FBX's and Unreal's unit) or ``"m"`` (values in metres,
        ``UnitScaleFactor`` 100). Either imports at the same size in Blender, Unity and Unreal.
    up_axis : ``"y"`` (default: SMPL's frame) or ``"z"`` (the data rotated so +Z is up and the body faces -Y).
    input_up_axis : the up axis of the input's world: ``"y"`` (default, SMPL's) or ``"z"`` (AMASS motions,
        whose root orientation stands the body along +Z). With ``"z"`` the root's rotation and path are turned
        so the body stands up in the file; the rest (bind) pose stays upright either way.
    root_bone : name of an extra bone at the origin above the pelvis (e.g. ``"root"``, Unreal's convention),
        or None.
    shape_keys : add the shape coefficients (at weight 0) and the expressions (animated) as blend shapes.
    pose_correctives : add the model's pose-corrective blend shapes, one per entry of ``R - I`` of every
        joint but the root, with weights keyed per frame: the skinned file then equals the full model.
    uv : write the model's UV map (default: whenever it has one).
    vertex_colors : optional (V, 3|4) colours (floats in [0, 1] or uint8), written as ``LayerElementColor``,
        e.g. :func:`smplcore.export.weight_colors` of the skinning weights.
    texture : optional diffuse-colour texture for the UV map, embedded as PNG: an image file, an (H, W, 3|4)
        uint8 array or ``"uv-grid"`` (needs the model's UV map and Pillow).
    rotation_order : Euler order of the rotation curves, one of :data:`ROTATION_ORDERS` (FBX's meaning: the
        first axis is applied first).
    name : name of the animation stack (default: the input file's stem, or ``"motion"``).
    progress : called with numbers of frames processed.

    Returns
    -------
    :class:`ExportReport`; ``pose_corrective_max`` is what the correctives add when they are not exported.
    """
    if unit not in _UNITS:
        raise ValueError(f"unit: expected 'cm' or 'm', got {unit!r}")
    if up_axis not in ("y", "z"):
        raise ValueError(f"up_axis: expected 'y' or 'z', got {up_axis!r}")
    if input_up_axis not in ("y", "z"):
        raise ValueError(f"input_up_axis: expected 'y' or 'z', got {input_up_axis!r}")
    order = str(rotation_order).upper()
    if order not in ROTATION_ORDERS:
        raise ValueError(f"rotation_order: expected one of {', '.join(ROTATION_ORDERS)}, got {rotation_order!r}")
    path = Path(path)
    if path.suffix.lower() != ".fbx":
        raise ValueError(f"path: expected a .fbx file, got {str(path)!r}")
    anim = source if isinstance(source, Animation) else prepare_animation(model, source, fps=fps, progress=progress)
    if fps is not None and isinstance(source, Animation):
        anim = dataclasses.replace(anim, fps=float(fps))
    facts = model.rig  # the public model contract (smplcore.model.Rig): bases, UV map, skinning
    posedirs = facts.posedirs if facts.has_pose_correctives else None
    if pose_correctives and posedirs is None:
        raise ValueError(f"pose_correctives: the {anim.model_type} model has no pose-corrective blend shapes")
    uv_map = None if facts.uv is None else (facts.uv.vt, facts.uv.ft)
    if uv and uv_map is None:
        raise ValueError(f"uv: the {anim.model_type} model has no UV map (vt/ft)")
    if texture is not None and (uv_map is None or uv is False):
        raise ValueError("texture: a texture needs the model's UV map; the model has none or uv=False was given")
    image = resolve_texture(texture)
    png = None if image is None else encode_png(image)
    if root_bone is not None and root_bone in anim.joint_names:
        raise ValueError(f"root_bone: {root_bone!r} is already a joint of the {anim.model_type} model")
    notes = list(anim.notes)

    per_metre, unit_scale = _UNITS[unit]
    axes = _Z_UP if up_axis == "z" else np.eye(3)

    def place(points: np.ndarray) -> np.ndarray:  # metres in SMPL's frame -> file units and axes
        return per_metre * (np.asarray(points, np.float64) @ axes.T)

    doc = Document()
    body = f"{anim.model_type}_body"
    faces = np.asarray(anim.faces, np.int64)
    normals = _vertex_normals(anim.rest_vertices, faces).astype(np.float64) @ axes.T
    colors = None
    if vertex_colors is not None:
        colors = _check_vertex_colors(vertex_colors, anim.rest_vertices.shape[0]).astype(np.float64) / 255.0
    model_id, geometry_id, material_id = add_mesh(
        doc, body, place(anim.rest_vertices), faces, normals, uv_map if uv is not False else None, colors
    )
    mesh = (model_id, geometry_id)
    if png is not None:
        add_texture(doc, material_id, png)
    bones = add_skeleton(doc, anim.joint_names, anim.parents, place(anim.offsets), root_bone, ROTATION_ORDERS[order])
    weights = np.asarray(anim.weights, np.float64)
    add_skin(doc, body, mesh, bones, anim.joint_names, weights, place(anim.rest_joints), facts.skinning == "dqs")

    shapes, corrective = _blend_shapes(model, anim, facts, shape_keys, posedirs if pose_correctives else None, notes)
    if progress is not None and posedirs is not None:
        progress(anim.num_frames)  # the correctives keyed or measured
    times = ktime(np.arange(anim.num_frames) / anim.fps)
    stop = int(times[-1])
    stack_name = name or (Path(anim.source).stem if anim.source and not anim.source.startswith("<") else "motion")
    layer = add_animation_stack(doc, stack_name, stop)
    if shapes:
        placed = [(shape_name, place(offsets), keyed) for shape_name, offsets, keyed in shapes]
        add_blend_shapes(doc, body, mesh[1], layer, placed, times)

    # Skeleton animation: a Z-up input world turns the root; the file's axes conjugate every local rotation
    rotations, root_path = anim.rotations, anim.root_positions
    if input_up_axis == "z":
        rotations = rotations.copy()
        rotations[:, 0] = _Z_UP.T @ rotations[:, 0]
        root_path = root_path @ _Z_UP
    angles = _euler_xyz(np.einsum("ab,tjbc,dc->tjad", axes, rotations, axes), order)
    root_path = place(root_path)
    bone_ids = bones[0]
    for j in range(anim.num_joints):
        channels = {axis: angles[:, j, k] for k, axis in enumerate("XYZ")}
        add_curves(doc, layer, bone_ids[j], "Lcl Rotation", channels, times)
    add_curves(doc, layer, bone_ids[0], "Lcl Translation", {a: root_path[:, k] for k, a in enumerate("XYZ")}, times)
    if progress is not None:
        progress(anim.num_frames)

    nodes = doc.nodes(
        creator=f"smplcore {_version()} FBX writer",
        up_axis=up_axis,
        unit_scale=unit_scale,
        fps=anim.fps,
        stop=stop,
        take=stack_name,
    )
    write_file(path, nodes)
    return ExportReport(
        path=path,
        format="fbx",
        num_frames=anim.num_frames,
        fps=anim.fps,
        num_joints=anim.num_joints + (root_bone is not None),
        num_vertices=anim.rest_vertices.shape[0],
        file_size=path.stat().st_size,
        max_model_influences=int((weights > 0).sum(axis=1).max()),
        pose_corrective_max=corrective,
        morph_targets=[s[0] for s in shapes],
        warnings=notes,
    )


def _blend_shapes(
    model: Any, anim: Animation, facts: Any, shape_keys: bool, posedirs: np.ndarray | None, notes: list[str]
) -> tuple[list[Shape], float | None]:
    """The blend shapes to write (offsets in metres, SMPL's frame) and, when the model has pose correctives
    that are not written (``posedirs`` None), how far they move the body; notes what is left out."""
    shapes: list[Shape] = []
    if shape_keys:
        shapes += [(f"beta_{k}", facts.shapedirs[:, :, k], None) for k in range(facts.shapedirs.shape[2])]
        if anim.expression is not None and anim.base_expression is not None and facts.exprdirs.shape[2]:
            expr = anim.expression - anim.base_expression
            animated = anim.expression_varies
            shapes += [
                (f"expr_{k}", facts.exprdirs[:, :, k], expr[:, k] if animated else None)
                for k in range(facts.exprdirs.shape[2])
            ]
    elif anim.expression_varies:
        message = (
            "the input's expression changes over time, which needs blend shapes: pass shape_keys=True "
            "(--morph-targets); the mesh shows the neutral expression"
        )
        notes.append(message)
        warn(message)
    if anim.dmpls is not None and facts.dmpldirs is not None:
        shapes += [(f"dmpl_{k}", facts.dmpldirs[:, :, k], anim.dmpls[:, k]) for k in range(anim.dmpls.shape[1])]
        shift = dmpl_joint_shift(model, anim.dmpls)
        if shift > 1e-6:
            notes.append(
                f"dmpls move the model's joints by up to {shift * 1000:.2f} mm; the exported skeleton uses the "
                "joints without soft tissue"
            )
    if posedirs is not None:
        features = (anim.rotations[:, 1:] - np.eye(3)).reshape(anim.num_frames, -1)  # (T, 9 (J - 1)): R - I
        for p in range(posedirs.shape[0]):
            joint, cell = anim.joint_names[1 + p // 9], p % 9
            shapes.append((f"pose_{joint}_{cell // 3}{cell % 3}", posedirs[p], features[:, p]))
        return shapes, None
    if not facts.has_pose_correctives:
        return shapes, None
    corrective = pose_corrective_error(model, anim)
    if corrective is not None:
        message = (
            f"the {anim.model_type} model has pose-corrective blend shapes, which are not exported: the "
            f"file differs from the model by up to {corrective * 1000:.1f} mm (pass pose_correctives=True "
            "to export them as blend shapes keyed per frame)"
        )
        notes.append(message)
        warn(message)
    return shapes, corrective
