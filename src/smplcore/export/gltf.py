"""Rigged, animated bodies as glTF 2.0 binary (``.glb``), written with pygltflib.

The file holds one scene with

* a skeleton: one node per model joint (named after it), children nested as in the model's kinematic
  tree; rest transforms are translations ``joint - parent joint`` with identity rotation (the root node:
  its rest position), i.e. the shaped body's rest pose in SMPL's frame, which is also glTF's (Y up,
  metres, the body facing +Z);
* a skinned mesh (node ``body``): the shaped rest mesh with smooth normals, ``JOINTS_0``/``WEIGHTS_0``
  holding the top 4 skinning weights of each vertex, renormalised (``influences=8`` adds a second set;
  Blender reads it, three.js only the first), and inverse bind matrices ``translate(-rest joint)``;
  when the model has a UV map (the open model, SMPL-X), ``TEXCOORD_0`` too, with the mesh split along
  the UV seams (glTF has one UV per vertex: a seam vertex becomes several copies that share position,
  normal, skin weights and morph offsets), and optionally an embedded base-colour texture (PNG);
* one animation: a rotation channel (unit quaternions x, y, z, w, sign-continuous, linear = slerp) for
  every joint and a translation channel for the root (rest root joint + ``transl``), keyed at the
  sequence's frame rate (times ``k / fps``);
* optionally morph targets (``morph_targets=True``): one per shape coefficient (``beta_0``, ...) and,
  for models with expressions, one per expression coefficient (``expr_0``, ...), named in
  ``mesh.extras.targetNames``. The body shape is baked into the base mesh, so shape targets rest at
  weight 0 (they are edits relative to the exported body; the skeleton does not follow them);
  expression weights are animated as the difference to the expression baked into the base mesh;
* DMPL soft tissue (a model with ``dmpl_path``, an input with ``dmpls``): always morph targets
  ``dmpl_0`` ..., their weights animated with the per-frame coefficients.

``engine="unreal"`` or ``"unity"`` writes the same body the way game-engine importers want it, beside the
exact export above (the default, unchanged): a ``root`` bone at the origin above the pelvis (the skin's
first joint, no vertex weight), lengths multiplied by ``unit_scale`` (Unreal: 100, centimetres; Unity: 1,
metres), the whole motion lifted so its lowest vertex over all frames touches y = 0 (feet on the ground),
4 normalised influences per vertex (the report gives the largest dropped weight and the vertex error),
and a morph-target weight channel keyed every frame whenever there are morph targets.

glTF skinning then reproduces the model's linear blend skinning without pose correctives: exactly
(to float32) with all weights kept, and within the error :class:`ExportReport` gives for the top-4
truncation.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import warn
from smplcore.export.animation import (
    Animation,
    ExportReport,
    Progress,
    pose_corrective_error,
    prepare_animation,
    top_k_weights,
    truncation_error,
)
from smplcore.export.gltf_buffer import (
    ARRAY_BUFFER,
    ELEMENT_ARRAY_BUFFER,
    FLOAT,
    UBYTE,
    UINT,
    USHORT,
    BufferBuilder,
)
from smplcore.export.soft_tissue import dmpl_joint_shift
from smplcore.uv import TextureInput, encode_png, model_uv, resolve_texture, split_seams

__all__ = ["save_glb"]

_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER
_FLOAT, _UBYTE, _USHORT, _UINT = FLOAT, UBYTE, USHORT, UINT


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (float32); vertices no face uses get +Y."""
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    length = np.linalg.norm(normals, axis=1)
    normals[length <= 1e-20] = (0.0, 1.0, 0.0)
    normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    normals = normals.astype(np.float32)
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


def _float32_weights(values: np.ndarray) -> np.ndarray:
    """Weights as float32 whose rows sum to one as closely as float32 allows."""
    w = values.astype(np.float32)
    residual = (1.0 - w.astype(np.float64).sum(axis=1)).astype(np.float32)
    rows = np.arange(w.shape[0])
    w[rows, 0] += residual  # the largest weight absorbs the rounding
    return w


def quaternions(rotations: np.ndarray) -> np.ndarray:
    """(T, J, 3, 3) rotation matrices -> (T, J, 4) unit quaternions (x, y, z, w), sign-continuous in time
    (each frame's quaternion in the same hemisphere as the previous frame's; the first with w >= 0)."""
    from scipy.spatial.transform import Rotation

    frames, joints = rotations.shape[:2]
    q = Rotation.from_matrix(rotations.reshape(-1, 3, 3)).as_quat().reshape(frames, joints, 4)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q[0] *= np.where(q[0, :, 3:] < 0, -1.0, 1.0)
    if frames > 1:
        flips = np.where(np.einsum("tjk,tjk->tj", q[1:], q[:-1]) < 0, -1.0, 1.0)
        q[1:] *= np.cumprod(flips, axis=0)[..., None]
    return q


def save_glb(
    path: str | Path,
    model: Any,
    source: Any,
    *,
    fps: float | None = None,
    morph_targets: bool = False,
    influences: int = 4,
    vertex_colors: Any = None,
    uv: bool | None = None,
    texture: TextureInput | None = None,
    name: str | None = None,
    progress: Progress | None = None,
    engine: str | None = None,
    unit_scale: float | None = None,
) -> ExportReport:
    """Write ``source`` on ``model`` as a rigged, animated glTF 2.0 binary.

    Parameters
    ----------
    path : the ``.glb`` to write (parent folders are created).
    model : a :class:`smplcore.BodyModel`.
    source : a :class:`~smplcore.motion.Motion`, a motion or parameter file, a dict of parameter arrays
        (one set or T frames), or an :class:`~smplcore.export.animation.Animation` (see
        :func:`~smplcore.export.animation.prepare_animation`).
    fps : frame rate (default: the motion's, 30 for parameter sets).
    morph_targets : add shape (and expression) components as morph targets (see the module docs).
    influences : joint weights kept per vertex, 4 (``JOINTS_0``/``WEIGHTS_0``, read by every viewer) or 8
        (adds ``JOINTS_1``/``WEIGHTS_1``).
    vertex_colors : optional (V, 3|4) colours (floats in [0, 1] or uint8), written as ``COLOR_0``, e.g.
        :func:`smplcore.export.weight_colors` of the skinning weights.
    uv : write the model's UV map as ``TEXCOORD_0`` (default: whenever the model has one, e.g. the open
        model and SMPL-X). glTF keeps one UV per vertex, so the mesh is split along the UV seams: the file
        then holds more vertices than the model, each a copy of a model vertex with its position, normal,
        skin weights, colour and morph-target offsets.
    texture : optional base-colour texture for the UV map: an image file, an (H, W, 3|4) uint8 array or
        ``"uv-grid"`` (:func:`smplcore.uv.uv_grid_texture`); embedded as PNG.
    name : name of the animation (default: the input file's stem, or ``"motion"``).
    progress : called with numbers of frames processed (two passes: preparing, measuring the skin error;
        a third for models with pose correctives).
    engine : ``"unreal"`` or ``"unity"``: the game-engine conventions of the module docs (root bone, unit
        scale, feet on the ground, 4 influences, morph weights every frame); default None, the exact export.
    unit_scale : lengths multiplier with ``engine`` (default: 100 for Unreal, centimetres; 1 for Unity).

    Returns
    -------
    :class:`ExportReport` with the top-4 truncation error (max / mean vertex displacement against
    full-weight skinning over all frames) and, for models with pose correctives, what they would add.
    """
    from smplcore._deps import require

    pygltflib = require("pygltflib", "save_glb", "export")

    if influences not in (4, 8):
        raise ValueError(f"influences: expected 4 or 8, got {influences!r}")
    if engine not in (None, "unreal", "unity"):
        raise ValueError(f"engine: expected 'unreal', 'unity' or None, got {engine!r}")
    if engine is not None and influences != 4:
        raise ValueError(f"influences: engines take 4 influences per vertex, got {influences} with engine={engine!r}")
    if unit_scale is not None and engine is None:
        raise ValueError("unit_scale: only with engine='unreal' or 'unity' (the exact export is in metres)")
    scale = float(unit_scale if unit_scale is not None else (100.0 if engine == "unreal" else 1.0))
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"unit_scale: expected a positive number, got {unit_scale!r}")
    anim = source if isinstance(source, Animation) else prepare_animation(model, source, fps=fps, progress=progress)
    if fps is not None and isinstance(source, Animation):
        anim = dataclasses.replace(anim, fps=float(fps))
    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise ValueError(f"path: expected a .glb file, got {str(path)!r}")
    notes = list(anim.notes)
    num_joints, num_verts = anim.num_joints, anim.rest_vertices.shape[0]
    uv_map = model_uv(model)
    if uv and uv_map is None:
        raise ValueError(f"uv: the {anim.model_type} model has no UV map (vt/ft)")
    if texture is not None and (uv_map is None or uv is False):
        raise ValueError("texture: a texture needs the model's UV map; the model has none or uv=False was given")
    image = resolve_texture(texture)
    split = split_seams(anim.faces, *uv_map) if uv_map is not None and uv is not False else None

    joints_idx, values, _ = top_k_weights(anim.weights, influences)
    err = truncation_error(anim, joints_idx, values, progress=progress)
    corrective = pose_corrective_error(model, anim) if getattr(model, "has_pose_correctives", False) else None
    if corrective is not None:
        if progress is not None:
            progress(anim.num_frames)
        message = (
            f"the {model.model_type} model has pose-corrective blend shapes, which glTF skinning cannot "
            f"express: the exported body differs from the model by up to {corrective * 1000:.1f} mm "
            "(it matches the model evaluated without pose correctives)"
        )
        notes.append(message)
        warn(message)

    gltf = pygltflib.GLTF2()
    gltf.asset = pygltflib.Asset(version="2.0", generator=f"smplcore {_version()} (pygltflib)")
    build = BufferBuilder(gltf)
    lift = np.zeros(3)
    if engine is not None:
        lift[1] = -_lowest_point(anim)

    # Skeleton: node j is joint j; the mesh node comes after the joints.
    offsets = (anim.offsets + np.where(np.arange(num_joints)[:, None] == 0, lift, 0.0)) * scale
    for j, joint_name in enumerate(anim.joint_names):
        gltf.nodes.append(
            pygltflib.Node(
                name=joint_name,
                translation=[float(v) for v in offsets[j]],
                children=[int(c) for c in np.flatnonzero(anim.parents == j)] or None,
            )
        )
    mesh_node = num_joints

    # Mesh (split along the UV seams when there is a UV map: `ids` picks each written vertex's model vertex).
    ids = np.arange(num_verts) if split is None else split.vertex_ids
    faces = np.asarray(anim.faces) if split is None else split.faces
    verts = ((anim.rest_vertices[ids] + lift) * scale).astype(np.float32)
    attributes: dict[str, int] = {
        "POSITION": build.accessor(verts, _FLOAT, target=_ARRAY_BUFFER, bounds=True, name="positions"),
        "NORMAL": build.accessor(
            _vertex_normals(anim.rest_vertices, np.asarray(anim.faces))[ids],
            _FLOAT,
            target=_ARRAY_BUFFER,
            name="normals",
        ),
    }
    if split is not None:  # glTF's UV origin is the top-left corner: v flipped
        texcoord = np.c_[split.uv[:, 0], 1.0 - split.uv[:, 1]]
        attributes["TEXCOORD_0"] = build.accessor(texcoord, _FLOAT, target=_ARRAY_BUFFER, name="texcoords")
    root_bone = engine is not None  # skin joint 0 is the root bone, joint j is skin joint j + 1
    joint_type = _UBYTE if num_joints + root_bone <= 256 else _USHORT
    joints_idx, values = joints_idx[ids], values[ids]
    joints_idx = np.where(values > 0, joints_idx + root_bone, 0)  # unused slots: joint 0, weight 0
    w32 = _float32_weights(values)
    for s in range(influences // 4):
        cols = slice(4 * s, 4 * s + 4)
        attributes[f"JOINTS_{s}"] = build.accessor(
            joints_idx[:, cols], joint_type, target=_ARRAY_BUFFER, name=f"joints_{s}"
        )
        attributes[f"WEIGHTS_{s}"] = build.accessor(w32[:, cols], _FLOAT, target=_ARRAY_BUFFER, name=f"weights_{s}")
    if vertex_colors is not None:
        from smplcore.export.mesh import _check_vertex_colors

        attributes["COLOR_0"] = build.accessor(
            _check_vertex_colors(vertex_colors, num_verts)[ids],
            _UBYTE,
            target=_ARRAY_BUFFER,
            normalized=True,
            name="colors",
        )
    index_type = _USHORT if len(ids) < 65535 else _UINT
    indices = build.accessor(faces.reshape(-1), index_type, target=_ELEMENT_ARRAY_BUFFER, name="indices")

    target_names: list[str] = []
    targets: list[dict[str, int]] = []
    expression_slot = None
    if morph_targets:
        rig = model.rig
        shape_dirs = rig.shapedirs
        for k in range(shape_dirs.shape[2]):
            target_names.append(f"beta_{k}")
            targets.append(
                {
                    "POSITION": build.accessor(
                        shape_dirs[ids, :, k] * scale, _FLOAT, target=_ARRAY_BUFFER, bounds=True, name=f"beta_{k}"
                    )
                }
            )
        expr_dirs = rig.exprdirs
        if expr_dirs.shape[2] and anim.expression is not None:
            expression_slot = len(targets)
            for k in range(expr_dirs.shape[2]):
                target_names.append(f"expr_{k}")
                targets.append(
                    {
                        "POSITION": build.accessor(
                            expr_dirs[ids, :, k] * scale,
                            _FLOAT,
                            target=_ARRAY_BUFFER,
                            bounds=True,
                            name=f"expr_{k}",
                        )
                    }
                )
    dmpl_slot = None
    if anim.dmpls is not None and model.rig.dmpldirs is not None:
        # soft tissue changes every frame: always morph targets (dmpl_0, ...), weights animated below
        dmpl_slot = len(targets)
        dmpl_dirs = model.rig.dmpldirs
        for k in range(dmpl_dirs.shape[2]):
            target_names.append(f"dmpl_{k}")
            targets.append(
                {
                    "POSITION": build.accessor(
                        dmpl_dirs[ids, :, k] * scale, _FLOAT, target=_ARRAY_BUFFER, bounds=True, name=f"dmpl_{k}"
                    )
                }
            )
        shift = dmpl_joint_shift(model, anim.dmpls)
        if shift > 1e-6:
            notes.append(
                f"dmpls move the model's joints by up to {shift * 1000:.2f} mm; the exported skeleton uses the "
                "joints without soft tissue"
            )
    if not morph_targets and anim.expression_varies:
        message = (
            "the input's expression changes over time, which needs morph targets: pass morph_targets=True "
            "(--morph-targets); the mesh shows the neutral expression"
        )
        notes.append(message)
        warn(message)

    primitive = pygltflib.Primitive(
        attributes=pygltflib.Attributes(**attributes),
        indices=indices,
        material=0,
        mode=pygltflib.TRIANGLES,
        targets=[pygltflib.Attributes(**t) for t in targets] or None,
    )
    mesh_weights = None
    if targets:
        mesh_weights = [0.0] * len(targets)
    gltf.meshes.append(
        pygltflib.Mesh(
            name=f"{anim.model_type}_body",
            primitives=[primitive],
            weights=mesh_weights,
            extras={"targetNames": target_names} if targets else {},
        )
    )
    base_texture = None
    if image is not None:
        gltf.images.append(
            pygltflib.Image(bufferView=build.raw(encode_png(image)), mimeType="image/png", name="base_color")
        )
        gltf.samplers.append(pygltflib.Sampler(magFilter=9729, minFilter=9987, wrapS=33071, wrapT=33071))
        gltf.textures.append(pygltflib.Texture(sampler=0, source=0, name="base_color"))
        base_texture = pygltflib.TextureInfo(index=0, texCoord=0)
    gltf.materials.append(
        pygltflib.Material(
            name="body",
            pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(
                baseColorFactor=[1.0, 1.0, 1.0, 1.0] if image is not None else [0.8, 0.72, 0.66, 1.0],
                baseColorTexture=base_texture,
                metallicFactor=0.0,
                roughnessFactor=0.7,
            ),
        )
    )

    # Skin: joint j of the skin is node j; inverse bind matrices translate(-rest joint), column-major.
    ibm = np.tile(np.eye(4), (num_joints + root_bone, 1, 1))
    ibm[root_bone:, :3, 3] = -(anim.rest_joints + lift) * scale
    ibm_accessor = build.accessor(
        np.ascontiguousarray(ibm.transpose(0, 2, 1)).reshape(num_joints + root_bone, 16),
        _FLOAT,
        name="inverse_bind_matrices",
    )
    gltf.nodes.append(pygltflib.Node(name="body", mesh=0, skin=0))
    top = 0
    if root_bone:  # the root bone: at the origin, the pelvis its only child
        top = len(gltf.nodes)
        gltf.nodes.append(pygltflib.Node(name="root", children=[0]))
    skin_joints = ([top] if root_bone else []) + list(range(num_joints))
    gltf.skins.append(
        pygltflib.Skin(name="skeleton", joints=skin_joints, skeleton=top, inverseBindMatrices=ibm_accessor)
    )
    gltf.scenes.append(pygltflib.Scene(name=anim.model_type, nodes=[top, mesh_node]))
    gltf.scene = 0

    # Animation.
    frames = anim.num_frames
    times = (np.arange(frames, dtype=np.float64) / anim.fps).astype(np.float32)
    time_accessor = build.accessor(times, _FLOAT, bounds=True, name="time")
    quats = quaternions(anim.rotations).astype(np.float32)
    samplers, channels = [], []

    def add_channel(node: int, path_name: str, output: int) -> None:
        samplers.append(pygltflib.AnimationSampler(input=time_accessor, output=output, interpolation="LINEAR"))
        channels.append(
            pygltflib.AnimationChannel(
                sampler=len(samplers) - 1, target=pygltflib.AnimationChannelTarget(node=node, path=path_name)
            )
        )

    add_channel(0, "translation", build.accessor((anim.root_positions + lift) * scale, _FLOAT, name="root_translation"))
    for j in range(num_joints):
        add_channel(j, "rotation", build.accessor(quats[:, j], _FLOAT, name=f"rotation_{anim.joint_names[j]}"))
    every_frame = engine is not None and bool(targets)  # engines import morph curves only when animated
    if (expression_slot is not None and anim.expression_varies) or dmpl_slot is not None or every_frame:
        weights = np.zeros((frames, len(targets)))
        expression, base = anim.expression, anim.base_expression  # both set for a model with expressions
        if expression_slot is not None and expression is not None and base is not None and anim.expression_varies:
            expr = expression - base
            weights[:, expression_slot : expression_slot + expr.shape[1]] = expr
        if dmpl_slot is not None and anim.dmpls is not None:
            weights[:, dmpl_slot : dmpl_slot + anim.dmpls.shape[1]] = anim.dmpls
        add_channel(mesh_node, "weights", build.accessor(weights.reshape(-1), _FLOAT, name="morph_weights"))
    animation_name = name or (Path(anim.source).stem if anim.source and not anim.source.startswith("<") else "motion")
    gltf.animations.append(pygltflib.Animation(name=animation_name, samplers=samplers, channels=channels))

    report = ExportReport(
        path=path,
        format="glb",
        num_frames=frames,
        fps=anim.fps,
        num_joints=num_joints,
        num_vertices=len(ids),
        influences=influences,
        max_model_influences=int((anim.weights > 0).sum(axis=1).max()),
        top4_max_error=err["max"],
        top4_mean_error=err["mean"],
        top4_vertices_affected=int(err["affected"]),
        top4_max_dropped_weight=err["max_dropped"],
        pose_corrective_max=corrective,
        morph_targets=target_names,
        warnings=notes,
        engine=engine,
        unit_scale=scale,
        ground_lift=float(lift[1]) if engine is not None else None,
    )
    gltf.asset.extras = {
        "smplcore": {
            "model_type": anim.model_type,
            "fps": anim.fps,
            "frames": frames,
            "betas": [float(b) for b in anim.betas],
            "joint_names": anim.joint_names,
            "skin_influences": influences,
            "skin_truncation_max_error_m": err["max"],
            "skin_truncation_mean_error_m": err["mean"],
            "pose_correctives_exported": False,
            "pose_corrective_max_m": corrective,
            "uv_seam_split": split is not None,
            "model_vertices": num_verts,
            "engine": engine,
            "unit_scale": scale,
            "ground_lift_m": float(lift[1]),
        }
    }

    while len(build.blob) % 4:
        build.blob.append(0)
    gltf.buffers.append(pygltflib.Buffer(byteLength=len(build.blob)))
    gltf.set_binary_blob(bytes(build.blob))
    path.parent.mkdir(parents=True, exist_ok=True)
    gltf.save_binary(str(path))
    report.file_size = path.stat().st_size
    return report


def _lowest_point(anim: Animation) -> float:
    """The lowest y of the skinned body (full weights, no correctives) over every frame of ``anim``."""
    from smplcore.export.animation import lbs

    lowest = np.inf
    for start in range(0, anim.num_frames, 64):
        stop = min(start + 64, anim.num_frames)
        posed = lbs(anim.rest_vertices, anim.skinning_matrices(slice(start, stop)), anim.weights)
        lowest = min(lowest, float(posed[..., 1].min()))
    return lowest


def _version() -> str:
    try:
        from smplcore import __version__

        return __version__
    except ImportError:  # pragma: no cover
        return "?"
