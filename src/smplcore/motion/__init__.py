"""Motion sequences (AMASS-style) and dataset processing.

* :class:`Motion`, :func:`load_motion`, :func:`save_motion`: one sequence (``Motion.slice``,
  ``Motion.resample``, ``Motion.model_params``).
* :func:`find_model_file`, :class:`ModelCache`, :class:`Evaluator`: the gendered model a file
  names, loaded once, evaluated in chunks.
* :func:`process_tree`, :class:`ProcessOptions`: a whole dataset to joints / meshes (``smplcore process``).
"""

from smplcore.motion.models import Evaluator, ModelCache, find_model_file, pick_gender
from smplcore.motion.process import ProcessOptions, Summary, options_from_recipe, process_file, process_tree
from smplcore.motion.resample import ResamplePlan
from smplcore.motion.resample import plan as resample_plan
from smplcore.motion.sequence import POSE_WIDTH, Motion, load_motion, save_motion

__all__ = [
    "POSE_WIDTH",
    "Evaluator",
    "ModelCache",
    "Motion",
    "ProcessOptions",
    "ResamplePlan",
    "Summary",
    "find_model_file",
    "load_motion",
    "options_from_recipe",
    "pick_gender",
    "process_file",
    "process_tree",
    "resample_plan",
    "save_motion",
]
