"""Real skeletons: motion-capture files (BVH) and keypoint skeletons, mapped onto a body model's joints.

* :func:`read_bvh` reads ``.bvh`` / ``.bvh.gz`` into a :class:`BVHClip` (any rotation order, End Sites,
  reference-pose frame 0 detected), with world joint positions by forward kinematics.
"""

from smplcore.skeletons.bvh import MAX_BVH_BYTES, parse_bvh, read_bvh
from smplcore.skeletons.clip import BVHClip

__all__ = ["BVHClip", "MAX_BVH_BYTES", "parse_bvh", "read_bvh"]
