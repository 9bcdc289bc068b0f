"""Offscreen rendering of posed meshes (needs the ``render`` extra: pyrender, trimesh, Pillow)."""

from smplcore.render.offscreen import CAMERAS, render_mesh, render_to_png, save_png
from smplcore.render.overlay import render_overlay, save_overlay, side_view

__all__ = ["CAMERAS", "render_mesh", "render_overlay", "render_to_png", "save_overlay", "save_png", "side_view"]
