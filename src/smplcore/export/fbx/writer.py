"""Rigged, animated bodies as FBX 7.4 binary (``.fbx``), for Blender, Unity, Unreal, Maya, MotionBuilder.

The file holds

* a mesh (``Geometry`` + ``Model``): the shaped rest mesh (betas applied), polygon indices (each face's last
  index stored as ``-(i + 1)``), smooth per-vertex normals, and the model's UV map when it has one
  (``LayerElementUV``, one UV per face corner, so nothing is split along the seams);
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
from smplcore.export.fbx.binary import I32, I64, write_file
from smplcore.export.fbx.document import Document, ktime, matrix, properties70

__all__ = ["save_fbx", "ROTATION_ORDERS"]

#: FBX's RotationOrder enum; "XYZ" = rotate about X first, then Y, then Z (matrix Rz @ Ry @ Rx)
ROTATION_ORDERS = {"XYZ": 0, "XZY": 1, "YZX": 2, "YXZ": 3, "ZXY": 4, "ZYX": 5}
_UNITS = {"cm": (100.0, 1.0), "m": (1.0, 100.0)}  # values per metre, UnitScaleFactor (cm per unit)
_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # +90 degrees about X: y -> z


def _translate(t: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


def _curves(doc: Document, layer: int, target: int, prop: str, channels: dict[str, np.ndarray], times) -> None:
    """An AnimationCurveNode on ``target``'s ``prop`` with one linear curve per channel (values (T,))."""
    short = {"Lcl Translation": "T", "Lcl Rotation": "R", "DeformPercent": "DeformPercent"}[prop]
    node_id, node = doc.new("AnimationCurveNode", short, "AnimCurveNode", "")
    properties70(node, *((f"d|{c}", "Number", "", "A", float(v[0])) for c, v in channels.items()))
    doc.connect(node_id, layer)
    doc.connect(node_id, target, prop)
    for channel, values in channels.items():
        curve_id, curve = doc.new("AnimationCurve", "", "AnimCurve", "")
        curve.add("Default", float(values[0]))
        curve.add("KeyVer", I32(4009))
        curve.add("KeyTime", times)
        curve.add("KeyValueFloat", np.asarray(values, np.float32))
        curve.add("KeyAttrFlags", np.array([0x4], np.int32))  # linear interpolation
        curve.add("KeyAttrDataFloat", np.zeros(4, np.float32))
        curve.add("KeyAttrRefCount", np.array([len(values)], np.int32))
        doc.connect(curve_id, node_id, f"d|{channel}")


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
    if root_bone is not None and root_bone in anim.joint_names:
        raise ValueError(f"root_bone: {root_bone!r} is already a joint of the {anim.model_type} model")
    notes = list(anim.notes)

    per_metre, unit_scale = _UNITS[unit]
    axes = _Z_UP if up_axis == "z" else np.eye(3)

    def place(points: np.ndarray) -> np.ndarray:  # metres in SMPL's frame -> file units and axes
        return per_metre * (np.asarray(points, np.float64) @ axes.T)

    doc = Document()
    body = f"{anim.model_type}_body"
    num_verts = anim.rest_vertices.shape[0]
    faces = np.asarray(anim.faces, np.int64)

    # Mesh
    geometry_id, geometry = doc.new("Geometry", body, "Geometry", "Mesh")
    properties70(geometry)
    geometry.add("GeometryVersion", I32(124))
    geometry.add("Vertices", place(anim.rest_vertices).reshape(-1))
    polygons = faces.astype(np.int32).copy()
    polygons[:, -1] = -polygons[:, -1] - 1
    geometry.add("PolygonVertexIndex", polygons.reshape(-1))
    from smplcore.export.gltf import _vertex_normals

    normals = _vertex_normals(anim.rest_vertices, faces).astype(np.float64) @ axes.T
    layer_normal = geometry.add("LayerElementNormal", I32(0))
    layer_normal.add("Version", I32(101))
    layer_normal.add("Name", "")
    layer_normal.add("MappingInformationType", "ByVertice")
    layer_normal.add("ReferenceInformationType", "Direct")
    layer_normal.add("Normals", normals.reshape(-1))
    layer_types = ["LayerElementNormal"]
    if uv_map is not None and uv is not False:
        vt, ft = uv_map
        layer_uv = geometry.add("LayerElementUV", I32(0))
        layer_uv.add("Version", I32(101))
        layer_uv.add("Name", "UVMap")
        layer_uv.add("MappingInformationType", "ByPolygonVertex")
        layer_uv.add("ReferenceInformationType", "IndexToDirect")
        layer_uv.add("UV", np.asarray(vt, np.float64).reshape(-1))
        layer_uv.add("UVIndex", np.asarray(ft, np.int32).reshape(-1))
        layer_types.append("LayerElementUV")
    if vertex_colors is not None:
        from smplcore.export.mesh import _check_vertex_colors

        rgba = _check_vertex_colors(vertex_colors, num_verts).astype(np.float64) / 255.0
        layer_color = geometry.add("LayerElementColor", I32(0))
        layer_color.add("Version", I32(101))
        layer_color.add("Name", "Col")
        layer_color.add("MappingInformationType", "ByPolygonVertex")
        layer_color.add("ReferenceInformationType", "IndexToDirect")
        layer_color.add("Colors", rgba.reshape(-1))
        layer_color.add("ColorIndex", faces.astype(np.int32).reshape(-1))
        layer_types.append("LayerElementColor")
    layer_material = geometry.add("LayerElementMaterial", I32(0))
    layer_material.add("Version", I32(101))
    layer_material.add("Name", "")
    layer_material.add("MappingInformationType", "AllSame")
    layer_material.add("ReferenceInformationType", "IndexToDirect")
    layer_material.add("Materials", np.zeros(1, np.int32))
    layer_types.append("LayerElementMaterial")
    layer = geometry.add("Layer", I32(0))
    layer.add("Version", I32(100))
    for kind in layer_types:
        element = layer.add("LayerElement")
        element.add("Type", kind)
        element.add("TypedIndex", I32(0))

    mesh_id, mesh = doc.new("Model", body, "Model", "Mesh")
    mesh.add("Version", I32(232))
    properties70(mesh, ("DefaultAttributeIndex", "int", "Integer", "", I32(0)))
    mesh.add("Shading", True)
    mesh.add("Culling", "CullingOff")
    doc.connect(mesh_id, 0)
    doc.connect(geometry_id, mesh_id)
    material_id, material = doc.new("Material", "body", "Material", "")
    material.add("Version", I32(102))
    material.add("ShadingModel", "phong")
    material.add("MultiLayer", I32(0))
    properties70(
        material,
        ("DiffuseColor", "Color", "", "A", 0.8, 0.72, 0.66),
        ("SpecularFactor", "Number", "", "A", 0.1),
    )
    doc.connect(material_id, mesh_id)

    # Skeleton
    rest_joints = anim.rest_joints
    bone_ids: list[int] = []
    root_id = None
    if root_bone is not None:
        root_id = _limb(doc, root_bone, np.zeros(3))
        doc.connect(root_id, 0)
    offsets = anim.offsets
    for j, joint in enumerate(anim.joint_names):
        bone_ids.append(_limb(doc, joint, place(offsets[j])))
        parent = int(anim.parents[j])
        doc.connect(bone_ids[j], bone_ids[parent] if parent >= 0 else (root_id if root_id is not None else 0))

    # Skin: every non-zero weight; bind = rest (translation only)
    skin_id, skin = doc.new("Deformer", body, "Deformer", "Skin")
    skin.add("Version", I32(101))
    skin.add("Link_DeformAcuracy", 50.0)
    skin.add("SkinningType", "DualQuaternion" if facts.skinning == "dqs" else "Linear")
    doc.connect(skin_id, geometry_id)
    weights = np.asarray(anim.weights, np.float64)
    bind_world = [_translate(place(rest_joints[j])) for j in range(anim.num_joints)]
    for j, joint in enumerate(anim.joint_names):
        cluster_id, cluster = doc.new("Deformer", joint, "SubDeformer", "Cluster")
        cluster.add("Version", I32(100))
        cluster.add("UserData", "", "")
        rows = np.flatnonzero(weights[:, j] > 0)
        cluster.add("Indexes", rows.astype(np.int32))
        cluster.add("Weights", weights[rows, j])
        cluster.add("Transform", matrix(np.linalg.inv(bind_world[j])))
        cluster.add("TransformLink", matrix(bind_world[j]))
        doc.connect(cluster_id, skin_id)
        doc.connect(bone_ids[j], cluster_id)
    pose_id, pose = doc.new("Pose", body, "Pose", "BindPose")
    pose.add("Type", "BindPose")
    pose.add("Version", I32(100))
    bound = [(mesh_id, np.eye(4))] + ([(root_id, np.eye(4))] if root_id is not None else [])
    bound += list(zip(bone_ids, bind_world, strict=True))
    pose.add("NbPoseNodes", I32(len(bound)))
    for node_id, world in bound:
        entry = pose.add("PoseNode")
        entry.add("Node", _id(node_id))
        entry.add("Matrix", matrix(world))

    # Blend shapes: name, (V, 3) offsets in metres, weights per frame (T,) or None (constant 0)
    frames = anim.num_frames
    shapes: list[tuple[str, np.ndarray, np.ndarray | None]] = []
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
        from smplcore.export.soft_tissue import dmpl_joint_shift

        shift = dmpl_joint_shift(model, anim.dmpls)
        if shift > 1e-6:
            notes.append(
                f"dmpls move the model's joints by up to {shift * 1000:.2f} mm; the exported skeleton uses the "
                "joints without soft tissue"
            )
    corrective = None
    if pose_correctives and posedirs is not None:
        features = (anim.rotations[:, 1:] - np.eye(3)).reshape(frames, -1)  # (T, 9 (J - 1)), row-major R - I
        for p in range(posedirs.shape[0]):
            joint, cell = anim.joint_names[1 + p // 9], p % 9
            shapes.append((f"pose_{joint}_{cell // 3}{cell % 3}", posedirs[p], features[:, p]))
        if progress is not None:
            progress(frames)
    elif posedirs is not None:
        corrective = pose_corrective_error(model, anim)
        if progress is not None:
            progress(frames)
        if corrective is not None:
            message = (
                f"the {anim.model_type} model has pose-corrective blend shapes, which are not exported: the "
                f"file differs from the model by up to {corrective * 1000:.1f} mm (pass pose_correctives=True "
                "to export them as blend shapes keyed per frame)"
            )
            notes.append(message)
            warn(message)

    times = ktime(np.arange(frames) / anim.fps)
    stack_name = name or (Path(anim.source).stem if anim.source and not anim.source.startswith("<") else "motion")
    stack_id, stack = doc.new("AnimationStack", stack_name, "AnimStack", "")
    stop = int(times[-1])
    properties70(
        stack,
        ("LocalStart", "KTime", "Time", "", _id(0)),
        ("LocalStop", "KTime", "Time", "", _id(stop)),
        ("ReferenceStart", "KTime", "Time", "", _id(0)),
        ("ReferenceStop", "KTime", "Time", "", _id(stop)),
    )
    layer_id, _ = doc.new("AnimationLayer", "BaseLayer", "AnimLayer", "")
    doc.connect(layer_id, stack_id)

    if shapes:
        blend_id, blend = doc.new("Deformer", body, "Deformer", "BlendShape")
        blend.add("Version", I32(100))
        doc.connect(blend_id, geometry_id)
        for shape_name, offsets_m, keyed in shapes:
            delta = place(offsets_m)
            rows = np.flatnonzero(np.any(delta != 0, axis=1))
            shape_id, shape = doc.new("Geometry", shape_name, "Geometry", "Shape")
            shape.add("Version", I32(100))
            shape.add("Indexes", rows.astype(np.int32))
            shape.add("Vertices", delta[rows].reshape(-1))
            channel_id, channel = doc.new("Deformer", shape_name, "SubDeformer", "BlendShapeChannel")
            channel.add("Version", I32(100))
            first = 0.0 if keyed is None else float(keyed[0]) * 100.0
            channel.add("DeformPercent", first)
            channel.add("FullWeights", np.array([100.0]))
            properties70(channel, ("DeformPercent", "Number", "", "A", first))
            doc.connect(channel_id, blend_id)
            doc.connect(shape_id, channel_id)
            if keyed is not None:
                _curves(doc, layer_id, channel_id, "DeformPercent", {"DeformPercent": 100.0 * keyed}, times)

    # Skeleton animation: a Z-up input world turns the root; the file's axes conjugate every local rotation
    rotations, root_path = anim.rotations, anim.root_positions
    if input_up_axis == "z":
        rotations = rotations.copy()
        rotations[:, 0] = _Z_UP.T @ rotations[:, 0]
        root_path = root_path @ _Z_UP
    local = np.einsum("ab,tjbc,dc->tjad", axes, rotations, axes)
    angles = _euler_xyz(local, order)
    root_path = place(root_path)
    for j in range(anim.num_joints):
        channels = {axis: angles[:, j, k] for k, axis in enumerate("XYZ")}
        _curves(doc, layer_id, bone_ids[j], "Lcl Rotation", channels, times)
    _curves(doc, layer_id, bone_ids[0], "Lcl Translation", {a: root_path[:, k] for k, a in enumerate("XYZ")}, times)
    if progress is not None:
        progress(frames)
    if order != "XYZ":
        for node in doc.objects:
            if node.name == "Model" and node.props[2] == "LimbNode":
                block = node.find("Properties70")
                if block is not None:
                    block.add("P", "RotationOrder", "enum", "", "", I32(ROTATION_ORDERS[order]))

    from smplcore.export.gltf import _version

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
        num_frames=frames,
        fps=anim.fps,
        num_joints=anim.num_joints + (root_bone is not None),
        num_vertices=num_verts,
        file_size=path.stat().st_size,
        max_model_influences=int((weights > 0).sum(axis=1).max()),
        pose_corrective_max=corrective,
        morph_targets=[s[0] for s in shapes],
        warnings=notes,
    )


def _id(value: int) -> I64:
    return I64(int(value))


def _limb(doc: Document, joint: str, translation: np.ndarray) -> int:
    """A LimbNode model (and its node attribute) at ``translation`` from its parent; returns its id."""
    bone_id, bone = doc.new("Model", joint, "Model", "LimbNode")
    bone.add("Version", I32(232))
    properties70(
        bone,
        ("InheritType", "enum", "", "", I32(1)),
        ("DefaultAttributeIndex", "int", "Integer", "", I32(0)),
        ("Lcl Translation", "Lcl Translation", "", "A", *map(float, translation)),
    )
    bone.add("Shading", True)
    bone.add("Culling", "CullingOff")
    attribute_id, attribute = doc.new("NodeAttribute", joint, "NodeAttribute", "LimbNode")
    properties70(attribute, ("Size", "double", "Number", "", 1.0))
    attribute.add("TypeFlags", "Skeleton")
    doc.connect(attribute_id, bone_id)
    return bone_id
