"""Open a .glb (and optionally a .bvh) in Blender through its Python module ``bpy`` and print, as JSON, the
skinned vertices and bone heads at some frames, converted back to glTF's Y-up frame.

Run with a Python that has ``bpy`` (``pip install bpy`` in a separate virtualenv)::

    python blender_check.py FILE.glb FPS FRAME[,FRAME...] [FILE.bvh]
"""

import json
import os
import sys

import bpy


def y_up(p):
    return [p[0], p[2], -p[1]]  # Blender's importers turn glTF/BVH Y-up into Z-up: (x, y, z) -> (x, -z, y)


def main():
    glb, fps, frames = sys.argv[1], int(round(float(sys.argv[2]))), [int(k) for k in sys.argv[3].split(",")]
    bvh = sys.argv[4] if len(sys.argv) > 4 else None
    out = {"version": bpy.app.version_string, "vertices": {}, "bones": {}, "bvh_bones": {}}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = fps  # the glTF importer keys times at the scene's frame rate
    bpy.ops.import_scene.gltf(filepath=glb)
    mesh_obj = next(o for o in scene.objects if o.type == "MESH")
    arm = next(o for o in scene.objects if o.type == "ARMATURE")
    for k in frames:
        scene.frame_set(k)
        evaluated = mesh_obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        out["vertices"][str(k)] = [y_up(mesh_obj.matrix_world @ v.co) for v in mesh.vertices]
        evaluated.to_mesh_clear()
        out["bones"][str(k)] = {b.name: y_up(arm.matrix_world @ b.head) for b in arm.pose.bones}
    if bvh:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        bpy.ops.import_anim.bvh(filepath=bvh, global_scale=1.0, rotate_mode="NATIVE", update_scene_fps=True)
        arm = next(o for o in scene.objects if o.type == "ARMATURE")
        first = int(arm.animation_data.action.frame_range[0])
        out["bvh_fps"] = scene.render.fps / scene.render.fps_base
        for k in frames:
            scene.frame_set(first + k)
            out["bvh_bones"][str(k)] = {b.name: y_up(arm.matrix_world @ b.head) for b in arm.pose.bones}
    sys.stdout.write("\nJSON:" + json.dumps(out) + "\n")
    sys.stdout.flush()


main()
os._exit(0)  # skip bpy's interpreter teardown, which can crash after the work is done
