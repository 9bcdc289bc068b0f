"""Import an .fbx with Blender's own FBX importer and print, as JSON, the skinned mesh vertices and the bone heads
at some frames (world space, converted back to SMPL's Y-up frame, metres), optionally rendering one frame.

Run inside Blender::

    blender -b --factory-startup --python-exit-code 1 -P fbx_blender_check.py -- FILE.fbx FRAME[,FRAME...] \
        [--png OUT.png] [--wide-sliders]

Frames are the file's keys (the importer shifts them by its ``anim_offset``, 1 frame by default).
``--wide-sliders`` widens every shape key's slider range to [-10, 10] after the import: Blender clamps a
shape key's value to its slider range (0..1 by default), and keyed pose correctives go negative.
"""

import json
import os
import sys

import bpy


def y_up(p):
    return [p[0], p[2], -p[1]]  # Blender is Z up; the importer turns the file's axes into Blender's


def render(path, mesh_obj):
    import mathutils

    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "TEXTURE" if mesh_obj.active_material else "SINGLE"  # the embedded one
    scene.render.resolution_x, scene.render.resolution_y = 420, 560
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 100
    world = bpy.data.worlds.new("w") if scene.world is None else scene.world
    scene.world = world
    world.color = (0.92, 0.92, 0.94)
    corners = [mesh_obj.matrix_world @ mathutils.Vector(c) for c in mesh_obj.bound_box]
    center = sum(corners, mathutils.Vector()) / 8
    height = max(c.z for c in corners) - min(c.z for c in corners)
    cam_data = bpy.data.cameras.new("cam")
    cam_data.lens = 50
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = center + mathutils.Vector((0.75, -2.0, 0.25)) * max(height, 1.0)
    cam.rotation_euler = (center - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def main():
    argv = sys.argv[sys.argv.index("--") + 1 :]
    fbx, frames = argv[0], [int(k) for k in argv[1].split(",")]
    png = argv[argv.index("--png") + 1] if "--png" in argv else None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.import_scene.fbx(filepath=fbx)
    mesh_obj = next(o for o in scene.objects if o.type == "MESH")
    arm = next(o for o in scene.objects if o.type == "ARMATURE")
    keys = mesh_obj.data.shape_keys
    if "--wide-sliders" in argv and keys is not None:
        for key in keys.key_blocks:
            key.slider_min, key.slider_max = -10.0, 10.0
    out = {
        "version": bpy.app.version_string,
        "fps": scene.render.fps / scene.render.fps_base,
        "bones": [b.name for b in arm.data.bones],
        "parents": {b.name: (b.parent.name if b.parent else None) for b in arm.data.bones},
        "shape_keys": [k.name for k in keys.key_blocks] if keys else [],
        "uv_layers": [layer.name for layer in mesh_obj.data.uv_layers],
        "vertex_groups": len(mesh_obj.vertex_groups),
        "images": [
            [node.image.name, list(node.image.size)]
            for slot in mesh_obj.material_slots
            if slot.material is not None and slot.material.node_tree is not None
            for node in slot.material.node_tree.nodes
            if node.type == "TEX_IMAGE" and node.image is not None
        ],
        "vertices": {},
        "heads": {},
    }
    for k in frames:
        scene.frame_set(k + 1)  # the importer's default anim_offset
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = mesh_obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        world = evaluated.matrix_world
        out["vertices"][str(k)] = [y_up(world @ v.co) for v in mesh.vertices]
        evaluated.to_mesh_clear()
        out["heads"][str(k)] = {b.name: y_up(arm.matrix_world @ b.head) for b in arm.pose.bones}
    if png:
        scene.frame_set(frames[-1] + 1)
        render(png, mesh_obj)
    sys.stdout.write("\nJSON:" + json.dumps(out) + "\n")
    sys.stdout.flush()


main()
os._exit(0)
