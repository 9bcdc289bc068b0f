"""Export: posed meshes (OBJ / PLY, needs trimesh), rigged animated bodies (glTF binary, needs pygltflib;
engine-ready with ``engine=``), VRM 1.0 avatars and VRM animation clips (:mod:`smplcore.export.vrm`, needs
pygltflib), rigged USD / USDZ (needs usd-core), FBX 7.4 binary (our own writer, NumPy only), skeleton motion
(BVH, NumPy + SciPy only) and parameters (``.smpl``, the SMPL-X Blender add-on npz; NumPy + SciPy)."""

from smplcore.export.animation import Animation, ExportReport, load_input, prepare_animation
from smplcore.export.bvh import save_bvh
from smplcore.export.fbx import save_fbx
from smplcore.export.gltf import save_glb
from smplcore.export.mesh import SUPPORTED_SUFFIXES, save_mesh, weight_colors
from smplcore.export.smplfile import SmplFile, load_blender_npz, read_smpl, save_blender_npz, save_smpl, write_smpl
from smplcore.export.usd import save_usd
from smplcore.export.vrm import save_vrm, save_vrma

__all__ = [
    "SUPPORTED_SUFFIXES",
    "Animation",
    "SmplFile",
    "ExportReport",
    "load_blender_npz",
    "load_input",
    "prepare_animation",
    "read_smpl",
    "save_blender_npz",
    "save_bvh",
    "save_fbx",
    "save_glb",
    "save_mesh",
    "save_smpl",
    "save_usd",
    "save_vrm",
    "save_vrma",
    "weight_colors",
    "write_smpl",
]
