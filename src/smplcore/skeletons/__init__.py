"""Real skeletons: motion-capture files (BVH) and 3D keypoint skeletons, mapped onto a body model's joints.

* :func:`read_bvh` reads ``.bvh`` / ``.bvh.gz`` into a :class:`BVHClip` (any rotation order, End Sites,
  reference-pose frame 0 detected), with world joint positions by forward kinematics.
* :mod:`~smplcore.skeletons.maps`: named :class:`SkeletonMap`\\ s (CMU Daz / MotionBuilder / 3dsMax releases,
  the FAIR capture, Human3.6M 17 / 32, MediaPipe, OpenPose BODY_25), found from a file's joint names.
* :func:`to_model_targets`: a clip or points to fitting targets (metres, Y up, weights), the units detected
  from the skeleton's size (:mod:`~smplcore.skeletons.units`).
* :func:`bone_lengths`: which target bones the model's shape space cannot reach, and by how much.
"""

from smplcore.skeletons.bvh import MAX_BVH_BYTES, parse_bvh, read_bvh
from smplcore.skeletons.clip import BVHClip
from smplcore.skeletons.diagnostics import BoneReport, bone_lengths
from smplcore.skeletons.mapping import SkeletonMap, Target
from smplcore.skeletons.maps import MAPS, detect_skeleton, skeleton_for_points, skeleton_map, skeleton_names
from smplcore.skeletons.targets import ModelTargets, leg_length, points_units, to_metres, to_model_targets
from smplcore.skeletons.units import UNIT_SCALES, Units, parse_units

__all__ = [
    "BVHClip",
    "BoneReport",
    "MAPS",
    "MAX_BVH_BYTES",
    "ModelTargets",
    "SkeletonMap",
    "Target",
    "UNIT_SCALES",
    "Units",
    "bone_lengths",
    "detect_skeleton",
    "leg_length",
    "parse_bvh",
    "parse_units",
    "points_units",
    "read_bvh",
    "skeleton_for_points",
    "skeleton_map",
    "skeleton_names",
    "to_metres",
    "to_model_targets",
]
