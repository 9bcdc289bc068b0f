"""Writing meshes to files (needs the ``export`` extra: trimesh)."""

from smplcore.export.mesh import SUPPORTED_SUFFIXES, save_mesh, weight_colors

__all__ = ["SUPPORTED_SUFFIXES", "save_mesh", "weight_colors"]
