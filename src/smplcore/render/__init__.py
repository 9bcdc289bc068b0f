"""Offscreen rendering of posed meshes (needs the ``render`` extra: pyrender, trimesh, Pillow)."""

from smplcore.render.offscreen import CAMERAS, render_mesh, render_to_png, save_png

__all__ = ["CAMERAS", "render_mesh", "render_to_png", "save_png"]
