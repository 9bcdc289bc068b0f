"""docs/usd_blender.png: a USD written by ``smplcore.export.save_usd``, opened by Blender's own USD importer (UsdSkel
skeleton, skin, UVs, the UsdPreviewSurface material with its texture) and rendered there, three frames side by side.

Two steps, two Pythons (Blender's ``bpy`` module lives in its own virtualenv: ``pip install bpy==4.2.0``)::

    PYTHONPATH=src python tools/render_usd_blender.py write /tmp/usd_doc      # the USD, by smplcore
    /path/to/bpy-venv/bin/python tools/render_usd_blender.py render /tmp/usd_doc docs/usd_blender.png
"""

from __future__ import annotations

import sys
from pathlib import Path

FRAMES = (0, 20, 40)


def write(folder: Path) -> None:
    import numpy as np
    from scipy.spatial.transform import Rotation

    import smplcore
    from smplcore.export import save_usd
    from smplcore.motion import load_motion
    from smplcore.motion.synthetic import write_sequence

    folder.mkdir(parents=True, exist_ok=True)
    write_sequence(folder / "walk.npz", 60, fps=30.0, model_type="smplh")
    motion = load_motion(folder / "walk.npz")
    # the synthetic walk is Z-up like AMASS: turned back into the model's Y-up frame; zero betas (the open model's
    # shape space is its own)
    turn = Rotation.from_euler("x", -90, degrees=True)
    poses = np.array(motion.poses)
    poses[:, :3] = (turn * Rotation.from_rotvec(poses[:, :3])).as_rotvec()
    trans = turn.apply(np.array(motion.trans))
    motion = type(motion)(**{**motion.__dict__, "poses": poses, "trans": trans, "betas": np.zeros(10)})
    report = save_usd(folder / "walk.usdc", smplcore.BodyModel(model_type="open"), motion, texture="uv-grid")
    print(report.summary())


def render(folder: Path, target: Path) -> None:
    import bpy
    from mathutils import Vector

    images = []
    for k in FRAMES:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.wm.usd_import(filepath=str(folder / "walk.usdc"), import_skeletons=True, scale=1.0)
        scene = bpy.context.scene
        scene.frame_set(k)
        mesh = next(o for o in scene.objects if o.type == "MESH")
        depsgraph = bpy.context.evaluated_depsgraph_get()
        points = [mesh.matrix_world @ v.co for v in mesh.evaluated_get(depsgraph).to_mesh().vertices]
        lo = Vector([min(p[i] for p in points) for i in range(3)])
        hi = Vector([max(p[i] for p in points) for i in range(3)])
        centre = (lo + hi) / 2
        camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
        scene.collection.objects.link(camera)
        camera.location = centre + Vector((0.6, -3.6, 0.3))
        camera.rotation_euler = (centre - camera.location).to_track_quat("-Z", "Y").to_euler()
        camera.data.lens = 50
        scene.camera = camera
        sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", type="SUN"))
        sun.data.energy = 3.0
        sun.rotation_euler = (0.8, 0.2, 0.6)
        scene.collection.objects.link(sun)
        world = bpy.data.worlds.new("world")
        world.use_nodes = True
        world.node_tree.nodes["Background"].inputs[0].default_value = (0.9, 0.9, 0.92, 1.0)
        world.node_tree.nodes["Background"].inputs[1].default_value = 0.8
        scene.world = world
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = 24
        scene.render.resolution_x, scene.render.resolution_y = 360, 540
        scene.render.film_transparent = False
        out = target.with_name(f"{target.stem}_{k}.png")
        scene.render.filepath = str(out)
        bpy.ops.render.render(write_still=True)
        images.append(out)
    # side by side, with Blender's own image API
    loaded = [bpy.data.images.load(str(p)) for p in images]
    width, height = loaded[0].size
    strip = bpy.data.images.new("strip", width * len(loaded), height)
    pixels = [0.0] * (width * len(loaded) * height * 4)
    for i, image in enumerate(loaded):
        src = list(image.pixels)
        for row in range(height):
            start = (row * width * len(loaded) + i * width) * 4
            pixels[start : start + width * 4] = src[row * width * 4 : (row + 1) * width * 4]
    strip.pixels = pixels
    strip.filepath_raw = str(target)
    strip.file_format = "PNG"
    strip.save()
    for p in images:
        p.unlink()


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write(Path(sys.argv[2]))
    else:
        render(Path(sys.argv[2]), Path(sys.argv[3]).resolve())
