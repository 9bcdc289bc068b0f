"""Textured meshes for :func:`smplcore.render.render_mesh`: a UV map and an image as a pyrender mesh."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.uv import SeamSplit


def smooth_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) area-weighted unit vertex normals of the unsplit mesh (so the seams do not show in the shading)."""
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 1e-20, normals / np.maximum(length, 1e-20), np.array([0.0, 1.0, 0.0]))


def textured_mesh(
    pyrender: Any,
    trimesh: Any,
    vertices: np.ndarray,
    faces: np.ndarray,
    split: SeamSplit,
    image: np.ndarray,
    alpha: float,
    smooth: bool,
) -> Any:
    """A pyrender mesh of ``vertices`` (V, 3) over ``faces`` (F, 3), split along the UV seams of ``split``,
    with ``image`` (H, W, 3|4 uint8) as its base-colour texture and opacity ``alpha``."""
    ids = split.vertex_ids
    normals = smooth_normals(vertices, faces)[ids]
    tm = trimesh.Trimesh(
        vertices=vertices[ids], faces=split.faces, vertex_normals=normals, process=False, validate=False
    )
    tm.visual = trimesh.visual.TextureVisuals(uv=split.uv)
    channels = "RGBA" if image.shape[2] == 4 else "RGB"
    texture = pyrender.Texture(source=image, source_channels=channels)
    blend = alpha < 1.0
    material = pyrender.MetallicRoughnessMaterial(
        baseColorFactor=[1.0, 1.0, 1.0, alpha],
        baseColorTexture=texture,
        metallicFactor=0.0,
        roughnessFactor=0.7,
        alphaMode="BLEND" if blend else "OPAQUE",
        doubleSided=not blend,
    )
    return pyrender.Mesh.from_trimesh(tm, material=material, smooth=smooth)
