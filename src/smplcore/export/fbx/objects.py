"""The FBX objects of a rigged body, each added to a :class:`~smplcore.export.fbx.document.Document` with its
connections: the mesh (geometry, model, material), the skeleton (LimbNode models), the skin with its bind pose,
blend shapes, and the animation stack with its curves. Values arrive in file units and axes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from smplcore.export.fbx.binary import I32, I64
from smplcore.export.fbx.document import Document, matrix, properties70

__all__ = [
    "add_mesh",
    "add_texture",
    "add_skeleton",
    "add_skin",
    "add_blend_shapes",
    "add_animation_stack",
    "add_curves",
]

#: a named blend shape: (name, (V, 3) offsets in file units, per-frame weights (T,) or None for a constant 0)
Shape = tuple[str, np.ndarray, "np.ndarray | None"]


def _layer_element(geometry, kind: str, name: str, mapping: str, reference: str):
    element = geometry.add(kind, I32(0))
    element.add("Version", I32(101))
    element.add("Name", name)
    element.add("MappingInformationType", mapping)
    element.add("ReferenceInformationType", reference)
    return element


def add_mesh(
    doc: Document,
    name: str,
    vertices: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray,
    uv: tuple[np.ndarray, np.ndarray] | None = None,
    colors: np.ndarray | None = None,
) -> tuple[int, int, int]:
    """A triangle mesh with per-vertex ``normals`` (V, 3), optional ``uv`` = (vt (T, 2), ft (F, 3)) and RGBA
    ``colors`` (V, 4) in [0, 1], under the scene root with a plain material. Returns (model id, geometry id,
    material id)."""
    geometry_id, geometry = doc.new("Geometry", name, "Geometry", "Mesh")
    properties70(geometry)
    geometry.add("GeometryVersion", I32(124))
    geometry.add("Vertices", np.asarray(vertices, np.float64).reshape(-1))
    polygons = np.asarray(faces, np.int32).copy()
    polygons[:, -1] = -polygons[:, -1] - 1  # a polygon's last index is stored as -(i + 1)
    geometry.add("PolygonVertexIndex", polygons.reshape(-1))
    kinds = ["LayerElementNormal"]
    _layer_element(geometry, kinds[-1], "", "ByVertice", "Direct").add("Normals", normals.reshape(-1))
    if uv is not None:
        kinds.append("LayerElementUV")
        element = _layer_element(geometry, kinds[-1], "UVMap", "ByPolygonVertex", "IndexToDirect")
        element.add("UV", np.asarray(uv[0], np.float64).reshape(-1))
        element.add("UVIndex", np.asarray(uv[1], np.int32).reshape(-1))
    if colors is not None:
        kinds.append("LayerElementColor")
        element = _layer_element(geometry, kinds[-1], "Col", "ByPolygonVertex", "IndexToDirect")
        element.add("Colors", np.asarray(colors, np.float64).reshape(-1))
        element.add("ColorIndex", np.asarray(faces, np.int32).reshape(-1))
    kinds.append("LayerElementMaterial")
    _layer_element(geometry, kinds[-1], "", "AllSame", "IndexToDirect").add("Materials", np.zeros(1, np.int32))
    layer = geometry.add("Layer", I32(0))
    layer.add("Version", I32(100))
    for kind in kinds:
        entry = layer.add("LayerElement")
        entry.add("Type", kind)
        entry.add("TypedIndex", I32(0))

    model_id, model = doc.new("Model", name, "Model", "Mesh")
    model.add("Version", I32(232))
    properties70(model, ("DefaultAttributeIndex", "int", "Integer", "", I32(0)))
    model.add("Shading", True)
    model.add("Culling", "CullingOff")
    doc.connect(model_id, 0)
    doc.connect(geometry_id, model_id)
    material_id, material = doc.new("Material", "body", "Material", "")
    material.add("Version", I32(102))
    material.add("ShadingModel", "phong")
    material.add("MultiLayer", I32(0))
    properties70(
        material,
        ("DiffuseColor", "Color", "", "A", 0.8, 0.72, 0.66),
        ("SpecularFactor", "Number", "", "A", 0.1),
    )
    doc.connect(material_id, model_id)
    return model_id, geometry_id, material_id


def add_texture(doc: Document, material: int, png: bytes, name: str = "base_color") -> None:
    """An embedded PNG (a ``Video`` clip with its ``Content``) as the diffuse-colour texture of ``material``,
    read through the mesh's UV map ``UVMap``."""
    filename = f"{name}.png"
    video_id, video = doc.new("Video", name, "Video", "Clip")
    video.add("Type", "Clip")
    properties70(video, ("Path", "KString", "XRefUrl", "", filename))
    video.add("UseMipMap", I32(0))
    video.add("Filename", filename)
    video.add("RelativeFilename", filename)
    video.add("Content", png)
    texture_id, texture = doc.new("Texture", name, "Texture", "")
    texture.add("Type", "TextureVideoClip")
    texture.add("Version", I32(202))
    texture.add("TextureName", f"{name}\x00\x01Texture")
    properties70(texture, ("UVSet", "KString", "", "", "UVMap"), ("UseMaterial", "bool", "", "", I32(1)))
    texture.add("Media", f"{name}\x00\x01Video")
    texture.add("FileName", filename)
    texture.add("RelativeFilename", filename)
    doc.connect(video_id, texture_id)
    doc.connect(texture_id, material, "DiffuseColor")


def _limb(doc: Document, joint: str, translation: np.ndarray, rotation_order: int) -> int:
    """A LimbNode model (and its node attribute) at ``translation`` from its parent; returns its id."""
    bone_id, bone = doc.new("Model", joint, "Model", "LimbNode")
    bone.add("Version", I32(232))
    entries: list[tuple] = [
        ("InheritType", "enum", "", "", I32(1)),
        ("DefaultAttributeIndex", "int", "Integer", "", I32(0)),
        ("Lcl Translation", "Lcl Translation", "", "A", *map(float, translation)),
    ]
    if rotation_order:
        entries.append(("RotationOrder", "enum", "", "", I32(rotation_order)))
    properties70(bone, *entries)
    bone.add("Shading", True)
    bone.add("Culling", "CullingOff")
    attribute_id, attribute = doc.new("NodeAttribute", joint, "NodeAttribute", "LimbNode")
    properties70(attribute, ("Size", "double", "Number", "", 1.0))
    attribute.add("TypeFlags", "Skeleton")
    doc.connect(attribute_id, bone_id)
    return bone_id


def add_skeleton(
    doc: Document,
    joint_names: Sequence[str],
    parents: np.ndarray,
    offsets: np.ndarray,
    root_bone: str | None = None,
    rotation_order: int = 0,
) -> tuple[list[int], int | None]:
    """One LimbNode per joint, rest translation ``offsets[j]`` (J, 3) from its parent, no rotation; with
    ``root_bone`` an extra bone at the origin above the root joint. Returns (bone ids, root bone id or None)."""
    root_id = None
    if root_bone is not None:
        root_id = _limb(doc, root_bone, np.zeros(3), rotation_order)
        doc.connect(root_id, 0)
    bone_ids: list[int] = []
    for j, joint in enumerate(joint_names):
        bone_ids.append(_limb(doc, joint, offsets[j], rotation_order))
        parent = int(parents[j])
        doc.connect(bone_ids[j], bone_ids[parent] if parent >= 0 else (root_id if root_id is not None else 0))
    return bone_ids, root_id


def add_skin(
    doc: Document,
    name: str,
    mesh: tuple[int, int],
    bones: tuple[list[int], int | None],
    joint_names: Sequence[str],
    weights: np.ndarray,
    bind_positions: np.ndarray,
    dual_quaternion: bool = False,
) -> None:
    """A skin deformer on ``mesh`` = (model id, geometry id): one cluster per bone with its non-zero ``weights``
    (V, J) column, bound at ``bind_positions`` (J, 3) (translation only: ``TransformLink`` = the bone's bind
    transform, ``Transform`` = its inverse, the mesh at the origin), and the bind pose of every node."""
    model_id, geometry_id = mesh
    bone_ids, root_id = bones
    skin_id, skin = doc.new("Deformer", name, "Deformer", "Skin")
    skin.add("Version", I32(101))
    skin.add("Link_DeformAcuracy", 50.0)
    skin.add("SkinningType", "DualQuaternion" if dual_quaternion else "Linear")
    doc.connect(skin_id, geometry_id)
    bind = np.tile(np.eye(4), (len(bone_ids), 1, 1))
    bind[:, :3, 3] = bind_positions
    for j, bone_id in enumerate(bone_ids):
        cluster_id, cluster = doc.new("Deformer", joint_names[j], "SubDeformer", "Cluster")
        cluster.add("Version", I32(100))
        cluster.add("UserData", "", "")
        rows = np.flatnonzero(weights[:, j] > 0)
        cluster.add("Indexes", rows.astype(np.int32))
        cluster.add("Weights", np.asarray(weights[rows, j], np.float64))
        cluster.add("Transform", matrix(np.linalg.inv(bind[j])))
        cluster.add("TransformLink", matrix(bind[j]))
        doc.connect(cluster_id, skin_id)
        doc.connect(bone_id, cluster_id)
    pose_id, pose = doc.new("Pose", name, "Pose", "BindPose")
    pose.add("Type", "BindPose")
    pose.add("Version", I32(100))
    bound = [(model_id, np.eye(4))] + ([(root_id, np.eye(4))] if root_id is not None else [])
    bound += list(zip(bone_ids, bind, strict=True))
    pose.add("NbPoseNodes", I32(len(bound)))
    for node_id, world in bound:
        entry = pose.add("PoseNode")
        entry.add("Node", I64(node_id))
        entry.add("Matrix", matrix(world))


def add_animation_stack(doc: Document, name: str, stop: int) -> int:
    """An animation stack ``name`` from time 0 to ``stop`` (ticks) with one layer; returns the layer's id."""
    stack_id, stack = doc.new("AnimationStack", name, "AnimStack", "")
    properties70(
        stack,
        ("LocalStart", "KTime", "Time", "", I64(0)),
        ("LocalStop", "KTime", "Time", "", I64(stop)),
        ("ReferenceStart", "KTime", "Time", "", I64(0)),
        ("ReferenceStop", "KTime", "Time", "", I64(stop)),
    )
    layer_id, _ = doc.new("AnimationLayer", "BaseLayer", "AnimLayer", "")
    doc.connect(layer_id, stack_id)
    return layer_id


def add_curves(
    doc: Document, layer: int, target: int, prop: str, channels: dict[str, np.ndarray], times: np.ndarray
) -> None:
    """An AnimationCurveNode on ``target``'s ``prop`` with one linear curve per channel (values (T,), keyed at
    ``times`` (T,) int64 ticks)."""
    short = {"Lcl Translation": "T", "Lcl Rotation": "R", "DeformPercent": "DeformPercent"}[prop]
    node_id, node = doc.new("AnimationCurveNode", short, "AnimCurveNode", "")
    properties70(node, *((f"d|{c}", "Number", "", "A", float(v[0])) for c, v in channels.items()))
    doc.connect(node_id, layer)
    doc.connect(node_id, target, prop)
    for channel, values in channels.items():
        curve_id, curve = doc.new("AnimationCurve", "", "AnimCurve", "")
        curve.add("Default", float(values[0]))
        curve.add("KeyVer", I32(4009))
        curve.add("KeyTime", np.asarray(times, np.int64))
        curve.add("KeyValueFloat", np.asarray(values, np.float32))
        curve.add("KeyAttrFlags", np.array([0x4], np.int32))  # linear interpolation
        curve.add("KeyAttrDataFloat", np.zeros(4, np.float32))
        curve.add("KeyAttrRefCount", np.array([len(values)], np.int32))
        doc.connect(curve_id, node_id, f"d|{channel}")


def add_blend_shapes(
    doc: Document, name: str, geometry: int, layer: int, shapes: Sequence[Shape], times: np.ndarray
) -> None:
    """A BlendShape deformer on ``geometry`` with one channel and shape per entry of ``shapes`` (offsets of the
    vertices that move; normal offsets zero); keyed weights become ``DeformPercent`` curves (weight 1 = 100)."""
    blend_id, blend = doc.new("Deformer", name, "Deformer", "BlendShape")
    blend.add("Version", I32(100))
    doc.connect(blend_id, geometry)
    for shape_name, offsets, keyed in shapes:
        rows = np.flatnonzero(np.any(offsets != 0, axis=1))
        shape_id, shape = doc.new("Geometry", shape_name, "Geometry", "Shape")
        shape.add("Version", I32(100))
        shape.add("Indexes", rows.astype(np.int32))
        shape.add("Vertices", np.asarray(offsets[rows], np.float64).reshape(-1))
        shape.add("Normals", np.zeros(3 * len(rows)))  # normal offsets: none (readers such as Assimp need the key)
        channel_id, channel = doc.new("Deformer", shape_name, "SubDeformer", "BlendShapeChannel")
        channel.add("Version", I32(100))
        first = 0.0 if keyed is None else float(keyed[0]) * 100.0
        channel.add("DeformPercent", first)
        channel.add("FullWeights", np.array([100.0]))
        properties70(channel, ("DeformPercent", "Number", "", "A", first))
        doc.connect(channel_id, blend_id)
        doc.connect(shape_id, channel_id)
        if keyed is not None:
            add_curves(doc, layer, channel_id, "DeformPercent", {"DeformPercent": 100.0 * keyed}, times)
