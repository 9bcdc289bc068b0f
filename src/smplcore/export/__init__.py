"""Export: posed meshes (OBJ / PLY, needs trimesh), rigged animated bodies (glTF binary, needs pygltflib;
engine-ready with ``engine=``), VRM 1.0 avatars and VRM animation clips (:mod:`smplcore.export.vrm`, needs
pygltflib) and skeleton motion (BVH, NumPy + SciPy only)."""

from smplcore.export.animation import Animation, ExportReport, load_input, prepare_animation
from smplcore.export.bvh import save_bvh
from smplcore.export.gltf import save_glb
from smplcore.export.mesh import SUPPORTED_SUFFIXES, save_mesh, weight_colors
from smplcore.export.vrm import save_vrm, save_vrma

__all__ = [
    "SUPPORTED_SUFFIXES",
    "Animation",
    "ExportReport",
    "load_input",
    "prepare_animation",
    "save_bvh",
    "save_glb",
    "save_mesh",
    "save_vrm",
    "save_vrma",
    "weight_colors",
]
