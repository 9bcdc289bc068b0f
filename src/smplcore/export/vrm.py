"""VRM 1.0 avatars (``.vrm``) and VRM animation clips (``.vrma``), written with pygltflib.

Both are glTF 2.0 binaries with one extension at the root:

* ``.vrm`` (``VRMC_vrm``, ``specVersion`` "1.0"): the shaped body as a skinned mesh on our skeleton, its
  humanoid bone map (:data:`HUMAN_BONES`: every required VRM bone, upper chest, shoulders, toes, jaw and
  eyes, and the fingers of models that have them -- SMPL+H, SMPL-X) and ``meta`` with the model's licence
  (the open model: CC0; an official SMPL-family file: the licence its user accepted, which VRM cannot
  grant further -- see :func:`default_meta`).
* ``.vrma`` (``VRMC_vrm_animation``): the same skeleton without a mesh, one rotation channel per humanoid
  bone and the hips translation per frame, which any VRM avatar plays (e.g. three-vrm's
  ``createVRMAnimationClip``).

The rest pose is the **VRM T-pose** (VRM 1.0 ``tpose.md``): Y up, facing +Z, arms, hands and the four
fingers straight along +X (left) / -X (right), thumbs between X and +Z at 45 degrees, parallel to the
ground; the soles on y = 0 and the rest pelvis at x = z = 0. :func:`vrm_tpose` finds the swing rotations
``C_j`` (world) of the arm, hand and finger joints that turn SMPL's rest pose (arms slightly down, fingers
as the model has them) into it. The mesh keeps SMPL's rest pose as its bind pose (inverse bind matrices
``translate(-joint)``) while the nodes' rest transforms are the T-pose (local rotations
``C_parent^T C_j``), so viewers show the T-pose at rest, and a node set to SMPL's local rotation ``R_j``
shows exactly the model's linear blend skinning -- no re-binding error. A ``.vrma`` holds those ``R_j`` on
nodes with the same rest; players retarget them through the rest rotations (three-vrm-animation turns them
into ``C_parent R_j C_j^T`` relative to the T-pose, what any avatar understands).

What VRM cannot hold is said: joints that are no VRM humanoid bone (SMPL's ``left_hand``/``right_hand``;
the eyes, which VRM animation drives by look-at only) are not animated in a ``.vrma`` (their rotation is
reported), pose correctives are dropped (measured), expressions are not written.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
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
from smplcore.export.gltf_buffer import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, UBYTE, UINT, USHORT, BufferBuilder
from smplcore.export.vrm_humanoid import (
    _LOOK_AT_BONES,
    HUMAN_BONES,
    REQUIRED_BONES,
    default_meta,
    humanoid_bones,
    vrm_tpose,
)

__all__ = [
    "HUMAN_BONES",
    "REQUIRED_BONES",
    "default_meta",
    "humanoid_bones",
    "save_vrm",
    "save_vrma",
    "vrm_tpose",
]


@dataclasses.dataclass
class _Rest:
    """The avatar's T-pose rest: joints, vertices and the offset putting the soles on y = 0."""

    rotations: np.ndarray  # (J, 3, 3) C_j
    joints: np.ndarray  # (J, 3) T-pose joints, offset applied
    vertices: np.ndarray  # (V, 3) T-pose vertices (full-weight LBS), offset applied
    offset: np.ndarray  # (3,) added to everything (pelvis at x = z = 0, soles at y = 0)


def _rest_of(anim: Animation) -> _Rest:
    rot, joints = vrm_tpose(anim.rest_joints, anim.parents, anim.joint_names)
    shift = joints - np.einsum("jab,jb->ja", rot, anim.rest_joints)  # x -> C_j x + shift_j
    weights = anim.weights / anim.weights.sum(axis=1, keepdims=True)
    verts = np.einsum("vj,jab,vb->va", weights, rot, anim.rest_vertices) + weights @ shift
    offset = np.array([-joints[0, 0], -verts[:, 1].min(), -joints[0, 2]])
    return _Rest(rot, joints + offset, verts + offset, offset)


def _rest_local_rotations(anim: Animation, rest: _Rest) -> np.ndarray:
    """(J, 3, 3) local rest rotation of each node, ``C_parent^T C_j``: the T-pose as SMPL local rotations."""
    parent_rot = np.concatenate([np.eye(3)[None], rest.rotations[anim.parents[1:]]], axis=0)
    return np.einsum("jba,jbc->jac", parent_rot, rest.rotations)


def _skeleton_nodes(gltf: Any, anim: Animation, rest: _Rest) -> int:
    """Node 0 ``root`` at the origin, then joint j as node j + 1 in the T-pose: translation ``joint - parent``
    of SMPL's rest (the pelvis: its T-pose position), rotation ``C_parent^T C_j``; returns the node of joint 0."""
    import pygltflib
    from scipy.spatial.transform import Rotation

    gltf.nodes.append(pygltflib.Node(name="root", children=[1]))
    offsets = anim.offsets.copy()
    offsets[0] = rest.joints[0]
    local = _rest_local_rotations(anim, rest)
    quats = Rotation.from_matrix(local).as_quat()
    for j, name in enumerate(anim.joint_names):
        children = [int(c) + 1 for c in np.flatnonzero(anim.parents == j)]
        turned = not np.allclose(local[j], np.eye(3), rtol=0, atol=1e-12)
        q = quats[j] * (1.0 if quats[j, 3] >= 0 else -1.0)
        gltf.nodes.append(
            pygltflib.Node(
                name=name,
                translation=[float(v) for v in offsets[j]],
                rotation=[float(v) for v in q / np.linalg.norm(q)] if turned else None,
                children=children or None,
            )
        )
    return 1


def _finish(gltf: Any, build: BufferBuilder, path: Path) -> int:
    import pygltflib

    while len(build.blob) % 4:
        build.blob.append(0)
    gltf.buffers.append(pygltflib.Buffer(byteLength=len(build.blob)))
    gltf.set_binary_blob(bytes(build.blob))
    path.parent.mkdir(parents=True, exist_ok=True)
    gltf.save_binary(str(path))
    return path.stat().st_size


def _animation_of(model: Any, source: Any, fps: float | None, progress: Progress | None) -> Animation:
    if source is None:
        source = {"betas": np.zeros(model.num_betas)}
    anim = source if isinstance(source, Animation) else prepare_animation(model, source, fps=fps, progress=progress)
    if fps is not None and isinstance(source, Animation):
        anim = dataclasses.replace(anim, fps=float(fps))
    return anim


def _note(notes: list[str], message: str) -> None:
    notes.append(message)
    warn(message)


def _check_path(path: str | Path, suffix: str) -> Path:
    path = Path(path)
    if path.suffix.lower() != suffix:
        raise ValueError(f"path: expected a {suffix} file, got {str(path)!r}")
    return path


def save_vrm(
    path: str | Path,
    model: Any,
    source: Any = None,
    *,
    meta: Mapping[str, Any] | None = None,
    uv: bool | None = None,
    texture: Any = None,
    progress: Progress | None = None,
) -> ExportReport:
    """Write the shaped body of ``model`` as a VRM 1.0 avatar in the VRM T-pose.

    Parameters
    ----------
    path : the ``.vrm`` to write.
    model : a :class:`smplcore.BodyModel` of a body (SMPL, SMPL+H, SMPL-X, the open model).
    source : where the body shape comes from: a parameter set or motion (see
        :func:`~smplcore.export.animation.prepare_animation`; its ``betas``, and the expression of its first
        frame); default the mean shape. The avatar holds no animation (write a ``.vrma`` for that).
    meta : fields of ``VRMC_vrm.meta`` replacing :func:`default_meta`'s (e.g. ``name``, ``authors``).
    uv : write the model's UV map as ``TEXCOORD_0`` (default: whenever the model has one).
    texture : optional base-colour texture for the UV map (an image file, an (H, W, 3|4) uint8 array or
        ``"uv-grid"``), embedded as PNG (see :func:`smplcore.export.save_glb`).
    progress : called with numbers of frames processed.

    Returns
    -------
    :class:`ExportReport` (``top4_*``: the 4-influence skin against full weights, over the T-pose and the
    source's frames).
    """
    from smplcore._deps import require

    pygltflib = require("pygltflib", "save_vrm", "export")
    from smplcore.export.gltf import _float32_weights, _version, _vertex_normals
    from smplcore.uv import encode_png, model_uv, resolve_texture, split_seams

    path = _check_path(path, ".vrm")
    anim = _animation_of(model, source, None, progress)
    if anim.num_frames > 1:
        anim = dataclasses.replace(
            anim,
            rotations=anim.rotations[:1],
            transl=anim.transl[:1],
            expression=None if anim.expression is None else anim.expression[:1],
            dmpls=None,
        )
    bones = humanoid_bones(anim.joint_names)
    rest = _rest_of(anim)
    notes = list(anim.notes)
    uv_map = model_uv(model)
    if uv and uv_map is None:
        raise ValueError(f"uv: the {anim.model_type} model has no UV map (vt/ft)")
    if texture is not None and (uv_map is None or uv is False):
        raise ValueError("texture: a texture needs the model's UV map; the model has none or uv=False was given")
    image = resolve_texture(texture)
    split = split_seams(anim.faces, *uv_map) if uv_map is not None and uv is not False else None

    joints_idx, values, _ = top_k_weights(anim.weights, 4)
    # the T-pose is anim's rest posed by world rotations C_j: its local rotations are C_parent^T C_j
    tpose_anim = dataclasses.replace(anim, rotations=_rest_local_rotations(anim, rest)[None], transl=np.zeros((1, 3)))
    err = truncation_error(tpose_anim, joints_idx, values)

    gltf = pygltflib.GLTF2()
    gltf.asset = pygltflib.Asset(version="2.0", generator=f"smplcore {_version()} (pygltflib)")
    build = BufferBuilder(gltf)
    first = _skeleton_nodes(gltf, anim, rest)
    num_joints = anim.num_joints

    ids = np.arange(anim.rest_vertices.shape[0]) if split is None else split.vertex_ids
    bind = anim.rest_vertices + rest.offset  # the bind pose: SMPL's rest (the nodes' rest shows the T-pose)
    faces = np.asarray(anim.faces) if split is None else split.faces
    attributes: dict[str, int] = {
        "POSITION": build.accessor(bind[ids], FLOAT, target=ARRAY_BUFFER, bounds=True, name="positions"),
        "NORMAL": build.accessor(
            _vertex_normals(bind, np.asarray(anim.faces))[ids], FLOAT, target=ARRAY_BUFFER, name="normals"
        ),
    }
    if split is not None:
        attributes["TEXCOORD_0"] = build.accessor(
            np.c_[split.uv[:, 0], 1.0 - split.uv[:, 1]], FLOAT, target=ARRAY_BUFFER, name="texcoords"
        )
    attributes["JOINTS_0"] = build.accessor(
        joints_idx[ids], UBYTE if num_joints <= 256 else USHORT, target=ARRAY_BUFFER, name="joints_0"
    )
    attributes["WEIGHTS_0"] = build.accessor(
        _float32_weights(values[ids]), FLOAT, target=ARRAY_BUFFER, name="weights_0"
    )
    indices = build.accessor(
        faces.reshape(-1), USHORT if len(ids) < 65535 else UINT, target=ELEMENT_ARRAY_BUFFER, name="indices"
    )
    gltf.meshes.append(
        pygltflib.Mesh(
            name=f"{anim.model_type}_body",
            primitives=[
                pygltflib.Primitive(
                    attributes=pygltflib.Attributes(**attributes), indices=indices, material=0, mode=pygltflib.TRIANGLES
                )
            ],
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
    ibm = np.tile(np.eye(4), (num_joints, 1, 1))
    ibm[:, :3, 3] = -(anim.rest_joints + rest.offset)
    gltf.skins.append(
        pygltflib.Skin(
            name="skeleton",
            joints=[first + j for j in range(num_joints)],
            skeleton=0,
            inverseBindMatrices=build.accessor(
                np.ascontiguousarray(ibm.transpose(0, 2, 1)).reshape(num_joints, 16),
                FLOAT,
                name="inverse_bind_matrices",
            ),
        )
    )
    mesh_node = len(gltf.nodes)
    gltf.nodes.append(pygltflib.Node(name="body", mesh=0, skin=0))
    gltf.scenes.append(pygltflib.Scene(name=anim.model_type, nodes=[0, mesh_node]))
    gltf.scene = 0

    corrective = pose_corrective_error(model, tpose_anim) if model.rig.has_pose_correctives else None
    if corrective is not None and corrective > 0:
        _note(
            notes,
            f"the avatar's T-pose mesh is linear blend skinning without the {anim.model_type} model's pose "
            f"correctives (they would move it by up to {corrective * 1000:.1f} mm); VRM avatars cannot hold them",
        )
    fields = default_meta(model)
    fields.update(meta or {})
    gltf.extensionsUsed = ["VRMC_vrm"]
    gltf.extensions = {
        "VRMC_vrm": {
            "specVersion": "1.0",
            "meta": fields,
            "humanoid": {"humanBones": {bone: {"node": first + j} for bone, j in bones.items()}},
        }
    }
    gltf.asset.extras = {
        "smplcore": {
            "model_type": anim.model_type,
            "betas": [float(b) for b in anim.betas],
            "joint_names": anim.joint_names,
            "rest": "VRM T-pose",
            "offset_m": [float(v) for v in rest.offset],
        }
    }
    report = ExportReport(
        path=path,
        format="vrm",
        num_frames=0,
        fps=anim.fps,
        num_joints=num_joints,
        num_vertices=len(ids),
        influences=4,
        max_model_influences=int((anim.weights > 0).sum(axis=1).max()),
        top4_max_error=err["max"],
        top4_mean_error=err["mean"],
        top4_vertices_affected=int(err["affected"]),
        top4_max_dropped_weight=err["max_dropped"],
        warnings=notes,
    )
    report.file_size = _finish(gltf, build, path)
    return report


def save_vrma(
    path: str | Path,
    model: Any,
    source: Any,
    *,
    fps: float | None = None,
    name: str | None = None,
    progress: Progress | None = None,
) -> ExportReport:
    """Write ``source`` as a VRM animation clip (``VRMC_vrm_animation``) that any VRM 1.0 avatar plays.

    Parameters
    ----------
    path : the ``.vrma`` to write.
    model : the :class:`smplcore.BodyModel` the motion is for (its skeleton, shaped by the source's
        ``betas``, is the clip's rest skeleton in the VRM T-pose).
    source : a motion, a motion or parameter file, or a dict of parameter arrays (see
        :func:`~smplcore.export.animation.prepare_animation`).
    fps : frame rate (default: the motion's, 30 for parameter sets).
    name : the animation's name (default: the input file's stem, or ``"motion"``).
    progress : called with numbers of frames processed.

    Returns
    -------
    :class:`ExportReport`; ``warnings`` name the rotations a VRM animation cannot carry.
    """
    from smplcore._deps import require

    pygltflib = require("pygltflib", "save_vrma", "export")
    from smplcore.export.gltf import _version, quaternions

    path = _check_path(path, ".vrma")
    anim = _animation_of(model, source, fps, progress)
    bones = humanoid_bones(anim.joint_names)
    rest = _rest_of(anim)
    notes = list(anim.notes)
    animated = {b: j for b, j in bones.items() if b not in _LOOK_AT_BONES}
    dropped = [j for j in range(anim.num_joints) if j not in animated.values()]
    if dropped:
        angle = np.degrees(
            np.arccos(np.clip((np.trace(anim.rotations[:, dropped], axis1=-2, axis2=-1) - 1) / 2, -1, 1))
        )
        moved = [(anim.joint_names[j], float(a)) for j, a in zip(dropped, angle.max(axis=0), strict=True) if a > 0.01]
        if moved:
            listed = ", ".join(f"{n} (up to {a:.1f} deg)" for n, a in moved)
            _note(notes, f"VRM animation has no bone for {listed}: these rotations are not in the clip")
    if model.rig.has_pose_correctives:
        _note(notes, "pose correctives are not part of a VRM animation: avatars show linear blend skinning")
    if anim.expression_varies:
        _note(notes, "the input's expression changes over time; VRM animation expressions are not written")

    gltf = pygltflib.GLTF2()
    gltf.asset = pygltflib.Asset(version="2.0", generator=f"smplcore {_version()} (pygltflib)")
    build = BufferBuilder(gltf)
    first = _skeleton_nodes(gltf, anim, rest)
    gltf.scenes.append(pygltflib.Scene(name="clip", nodes=[0]))
    gltf.scene = 0

    frames = anim.num_frames
    times = (np.arange(frames, dtype=np.float64) / anim.fps).astype(np.float32)
    time_accessor = build.accessor(times, FLOAT, bounds=True, name="time")
    quats = quaternions(anim.rotations).astype(np.float32)  # SMPL's local rotations: nodes rest in SMPL's frames
    samplers: list[Any] = []
    channels: list[Any] = []

    def add(node: int, target: str, output: int) -> None:
        samplers.append(pygltflib.AnimationSampler(input=time_accessor, output=output, interpolation="LINEAR"))
        channels.append(
            pygltflib.AnimationChannel(
                sampler=len(samplers) - 1, target=pygltflib.AnimationChannelTarget(node=node, path=target)
            )
        )

    add(first, "translation", build.accessor(anim.root_positions + rest.offset, FLOAT, name="hips_translation"))
    for bone, j in animated.items():
        add(first + j, "rotation", build.accessor(quats[:, j], FLOAT, name=f"rotation_{bone}"))
    animation_name = name or (Path(anim.source).stem if anim.source and not anim.source.startswith("<") else "motion")
    gltf.animations.append(pygltflib.Animation(name=animation_name, samplers=samplers, channels=channels))
    gltf.extensionsUsed = ["VRMC_vrm_animation"]
    gltf.extensions = {
        "VRMC_vrm_animation": {
            "specVersion": "1.0",
            "humanoid": {"humanBones": {bone: {"node": first + j} for bone, j in animated.items()}},
        }
    }
    gltf.asset.extras = {
        "smplcore": {
            "model_type": anim.model_type,
            "fps": anim.fps,
            "frames": frames,
            "betas": [float(b) for b in anim.betas],
            "rest": "VRM T-pose",
            "offset_m": [float(v) for v in rest.offset],
        }
    }
    report = ExportReport(
        path=path, format="vrma", num_frames=frames, fps=anim.fps, num_joints=len(animated), warnings=notes
    )
    report.file_size = _finish(gltf, build, path)
    return report
