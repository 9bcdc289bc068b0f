"""Motion sequences (AMASS-style) and dataset processing."""

from smplcore.motion.sequence import POSE_WIDTH, Motion, load_motion, save_motion

__all__ = ["POSE_WIDTH", "Motion", "load_motion", "save_motion"]
