"""The math of the SMPL family, written once for NumPy and PyTorch."""

from smplcore.engine.body import (
    BodyArrays,
    forward,
    posed_vertex_subset,
    rest_joints,
    rest_vertices,
    shaped_vertices,
    vertex_columns,
)
from smplcore.engine.landmarks import barycentric_points, contour_rows
from smplcore.engine.rotations import pose_features, rodrigues
from smplcore.engine.skeleton import KinematicTree, skin, skinning_transforms, world_transforms

__all__ = [
    "BodyArrays",
    "KinematicTree",
    "barycentric_points",
    "contour_rows",
    "forward",
    "pose_features",
    "posed_vertex_subset",
    "rest_joints",
    "rest_vertices",
    "rodrigues",
    "shaped_vertices",
    "skin",
    "skinning_transforms",
    "vertex_columns",
    "world_transforms",
]
