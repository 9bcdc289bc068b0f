"""Export: posed meshes (OBJ / PLY, needs trimesh), rigged animated bodies (glTF binary, needs pygltflib)
skeleton motion (BVH, NumPy + SciPy only) and rigged animated bodies as FBX 7.4 binary (our own writer,
NumPy only)."""

from smplcore.export.animation import Animation, ExportReport, load_input, prepare_animation
from smplcore.export.bvh import save_bvh
from smplcore.export.fbx import save_fbx
from smplcore.export.gltf import save_glb
from smplcore.export.mesh import SUPPORTED_SUFFIXES, save_mesh, weight_colors

__all__ = [
    "SUPPORTED_SUFFIXES",
    "Animation",
    "ExportReport",
    "load_input",
    "prepare_animation",
    "save_bvh",
    "save_fbx",
    "save_glb",
    "save_mesh",
    "weight_colors",
]
