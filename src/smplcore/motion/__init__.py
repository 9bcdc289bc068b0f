"""Motion sequences (AMASS-style) and dataset processing.

* :class:`Motion`, :func:`load_motion`, :func:`save_motion`: one sequence (``Motion.slice``,
  ``Motion.resample``, ``Motion.model_params``).
* :class:`ModelCache`, :class:`Evaluator`: the gendered model a file names (found by
  :func:`smplcore.io.locate.locate_model_file`), loaded once, evaluated in chunks.
* :func:`process_tree`, :class:`ProcessOptions`: a whole dataset to joints / meshes (``smplcore process``);
  :class:`ProcessFailed` when files failed, :data:`EXIT_DISK_FULL` the exit status of a run stopped by a full disk.
"""

from smplcore.motion.models import Evaluator, ModelCache, pick_gender
from smplcore.motion.process import (
    EXIT_DISK_FULL,
    DiskFullError,
    OutputSizeWarning,
    ProcessError,
    ProcessFailed,
    ProcessOptions,
    Summary,
    options_from_recipe,
    process_file,
    process_tree,
)
from smplcore.motion.resample import ResamplePlan
from smplcore.motion.resample import plan as resample_plan
from smplcore.motion.sequence import (
    POSE_WIDTH,
    Motion,
    ShapeSpaceWarning,
    load_motion,
    motion_from_arrays,
    save_motion,
)

__all__ = [
    "EXIT_DISK_FULL",
    "POSE_WIDTH",
    "DiskFullError",
    "Evaluator",
    "ModelCache",
    "Motion",
    "OutputSizeWarning",
    "ProcessError",
    "ProcessFailed",
    "ProcessOptions",
    "ResamplePlan",
    "ShapeSpaceWarning",
    "Summary",
    "load_motion",
    "motion_from_arrays",
    "options_from_recipe",
    "pick_gender",
    "process_file",
    "process_tree",
    "resample_plan",
    "save_motion",
]
