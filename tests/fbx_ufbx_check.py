"""Read an .fbx with ufbx (an independent FBX reader, PyPI ``ufbx``) and write what it finds as an ``.npz``: the
scene settings, the skeleton, the skin weights, the blend shapes, UVs and -- evaluated by ufbx itself
(``evaluate_scene`` with skinning) -- the posed vertices and joints at some frames. Geometry is converted by
ufbx to metres and SMPL's Y-up frame. Run in a subprocess::

    python fbx_ufbx_check.py FILE.fbx FRAME[,FRAME...] OUT.npz

The binding (ufbx 0.0.5) crashes when a wrapper of a scene object is freed and the object is reached again,
so every wrapper this script touches is kept alive (``hold``) until ``os._exit``.
"""

import json
import os
import sys

import numpy as np
import ufbx

_KEEP = []


def hold(value):
    _KEEP.append(value)
    return value


def items(owner, name):
    """The elements of list property ``name`` of ``owner``, each wrapper kept alive."""
    values = hold(getattr(owner, name))
    return [hold(values[i]) for i in range(len(values))]


def vec3(values):
    values = hold(values)
    return np.array([[values[i].x, values[i].y, values[i].z] for i in range(len(values))], dtype=np.float64)


def position(m):
    return [m.c3.x, m.c3.y, m.c3.z]


def main():
    path, frames, out = sys.argv[1], [int(k) for k in sys.argv[2].split(",")], sys.argv[3]
    scene = hold(
        ufbx.load_file(
            path,
            target_axes=ufbx.axes_right_handed_y_up,
            target_unit_meters=1.0,
            space_conversion=ufbx.SpaceConversion.MODIFY_GEOMETRY,
        )
    )
    settings, metadata = hold(scene.settings), hold(scene.metadata)
    info = {
        "version": metadata.version,
        "warnings": [hold(w).description for w in items(metadata, "warnings")],
        "unit_meters": settings.original_unit_meters,
        "up": int(settings.original_axis_up),
        "fps": settings.frames_per_second,
    }
    mesh = items(scene, "meshes")[0]
    bones = [n for n in items(scene, "nodes") if hold(n.bone) is not None]
    info["bones"] = [b.name for b in bones]
    parents = {}
    for b in bones:
        parent = hold(b.parent)
        parents[b.name] = parent.name if parent is not None and hold(parent.bone) is not None else None
    info["parents"] = parents
    info["rotation_orders"] = sorted({int(b.rotation_order) for b in bones})
    skin = items(mesh, "skin_deformers")[0]
    clusters = items(skin, "clusters")
    info["skinning_method"] = int(skin.skinning_method)
    info["clusters"] = [hold(c.bone_node).name for c in clusters]
    channels = [c for d in items(mesh, "blend_deformers") for c in items(d, "channels")]
    info["blend_channels"] = [c.name for c in channels]
    stack = items(scene, "anim_stacks")[0]
    info["stack"] = stack.name
    info["time_end"] = stack.time_end
    uv_sets = items(mesh, "uv_sets")
    info["uv_sets"] = [u.name for u in uv_sets]
    num_vertices = len(hold(mesh.vertices))
    indices = hold(mesh.vertex_indices)
    arrays = {
        "rest_vertices": vec3(mesh.vertices),
        "vertex_indices": np.array([indices[i] for i in range(len(indices))], dtype=np.int64),
        "bind_positions": np.array([position(hold(c.bind_to_world)) for c in clusters]),
    }
    weights = np.zeros((num_vertices, len(clusters)))
    for j, cluster in enumerate(clusters):
        rows, values = hold(cluster.vertices), hold(cluster.weights)
        weights[[rows[i] for i in range(len(rows))], j] = [values[i] for i in range(len(values))]
    arrays["weights"] = weights
    if uv_sets:
        uv = hold(uv_sets[0].vertex_uv)
        values, idx = hold(uv.values), hold(uv.indices)
        arrays["uv_values"] = np.array([[values[i].x, values[i].y] for i in range(len(values))])
        arrays["uv_indices"] = np.array([idx[i] for i in range(len(idx))], dtype=np.int64)
    textures = items(scene, "textures")
    info["textures"] = [t.name for t in textures]
    if textures:
        arrays["texture_content"] = np.frombuffer(textures[0].content, dtype=np.uint8)
        info["texture_uv_set"] = textures[0].uv_set
        material = items(mesh, "materials")[0]
        diffuse = hold(hold(hold(material.fbx).diffuse_color).texture)
        info["diffuse_texture"] = None if diffuse is None else diffuse.name
    color_sets = items(mesh, "color_sets")
    info["color_sets"] = [c.name for c in color_sets]
    if color_sets:
        color = hold(color_sets[0].vertex_color)
        values, idx = hold(color.values), hold(color.indices)
        rgba = [[values[i].x, values[i].y, values[i].z, values[i].w] for i in range(len(values))]
        arrays["color_corners"] = np.array(rgba)[[idx[i] for i in range(len(idx))]]
    if channels:
        offsets = []
        for channel in channels:
            shape = hold(channel.target_shape)
            rows = hold(shape.offset_vertices)
            dense = np.zeros((num_vertices, 3))
            dense[[rows[i] for i in range(len(rows))]] = vec3(shape.position_offsets)
            offsets.append(dense)
        arrays["shape_offsets"] = np.stack(offsets)
    anim = hold(scene.anim)
    fps = info["fps"]
    for k in frames:
        evaluated = hold(ufbx.evaluate_scene(scene, anim, k / fps, evaluate_skinning=True))
        emesh = items(evaluated, "meshes")[0]
        verts = vec3(hold(emesh.skinned_position).values)
        if emesh.skinned_is_local:
            m = hold(items(emesh, "instances")[0].geometry_to_world)
            rot = np.array([[m.c0.x, m.c1.x, m.c2.x], [m.c0.y, m.c1.y, m.c2.y], [m.c0.z, m.c1.z, m.c2.z]])
            verts = verts @ rot.T + position(m)
        arrays[f"vertices_{k}"] = verts
        arrays[f"joints_{k}"] = np.array(
            [position(hold(hold(evaluated.find_node(b.name)).node_to_world)) for b in bones]
        )
        arrays[f"blend_weights_{k}"] = np.array([c.evaluate_blend_weight(anim, k / fps) for c in channels])
    np.savez(out, info=json.dumps(info), **arrays)
    sys.stdout.flush()


main()
os._exit(0)  # skip the binding's teardown
