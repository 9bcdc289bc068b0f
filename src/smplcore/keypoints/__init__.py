"""Keypoint conventions by name: COCO, OpenPose, H36M, MediaPipe, MPII, COCO-WholeBody and the SMPL family.

NumPy and torch alike (torch is never imported unless a tensor is passed)::

    from smplcore import keypoints
    keypoints.names("coco17")                       # the 17 names, in COCO's order
    out, mask = keypoints.convert(joints, src=model, dst="openpose25")
    reg = keypoints.Regressor.load("J_regressor_h36m.npy", convention="h36m17")
    h36m = reg.apply(vertices)                      # (..., 17, 3)
"""

from smplcore.keypoints.aliases import ALIASES, FALSE_FRIENDS, canonical, canonical_names, own_names
from smplcore.keypoints.approximate import APPROXIMATE, SYNTHESIS, Approximation
from smplcore.keypoints.conventions import CONVENTIONS, conventions, names
from smplcore.keypoints.convert import Layout, Plan, convert, layout, plan
from smplcore.keypoints.readers import KeypointArray, read_coco, read_openpose
from smplcore.keypoints.regressor import Regressor, load_regressors, open_model_regressor

__all__ = [
    "ALIASES",
    "APPROXIMATE",
    "Approximation",
    "CONVENTIONS",
    "FALSE_FRIENDS",
    "KeypointArray",
    "Layout",
    "Plan",
    "Regressor",
    "SYNTHESIS",
    "canonical",
    "canonical_names",
    "conventions",
    "convert",
    "layout",
    "load_regressors",
    "names",
    "open_model_regressor",
    "own_names",
    "plan",
    "read_coco",
    "read_openpose",
]
