"""Export: posed meshes (OBJ / PLY, needs trimesh), rigged animated bodies (glTF binary, needs pygltflib;
USD / USDZ, needs usd-core) and skeleton motion (BVH, NumPy + SciPy only)."""

from smplcore.export.animation import Animation, ExportReport, load_input, prepare_animation
from smplcore.export.bvh import save_bvh
from smplcore.export.gltf import save_glb
from smplcore.export.mesh import SUPPORTED_SUFFIXES, save_mesh, weight_colors
from smplcore.export.usd import save_usd

__all__ = [
    "SUPPORTED_SUFFIXES",
    "Animation",
    "ExportReport",
    "load_input",
    "prepare_animation",
    "save_bvh",
    "save_glb",
    "save_mesh",
    "save_usd",
    "weight_colors",
]
