"""``smplcore fit`` on real skeletons: BVH motion capture (``.bvh``, ``.bvh.gz``) and the units of 3D joints.

A BVH is read by :func:`smplcore.skeletons.read_bvh`; its skeleton map is found from its joint names (or
``--skeleton``), its units and up axis from its leg length (or ``--units``), a reference-pose frame 0 is dropped,
and the motion is fitted as one person (shared betas) at the clip's frame rate. Each detection is said in the
run's summary (``notes``). A ``.npy`` of joints with a leg (hips, knees, ankles) is checked the same way:
centimetres or millimetres are converted to metres with a note, a leg that is no person's in any unit is refused
(without a leg, :func:`smplcore.fit.fit_joints` refuses a size 10x off the model's); ``--skeleton`` reads its points
as a keypoint skeleton (``h36m17``, ``mediapipe33``, ...).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

BVH_SUFFIXES = (".bvh", ".bvh.gz")


def is_bvh(path: Path) -> bool:
    return path.name.lower().endswith(BVH_SUFFIXES)


def input_stem(path: Path) -> str:
    """The output name of an input file: ``clip.bvh.gz`` -> ``clip``, ``joints.npy`` -> ``joints``."""
    return path.name[: -len(".bvh.gz")] if path.name.lower().endswith(".bvh.gz") else path.stem


def bvh_targets(path: Path, settings: Any, model: Any) -> Any:
    """The :class:`smplcore.skeletons.ModelTargets` of a BVH file (skeleton, units detected or given)."""
    from smplcore import skeletons

    return skeletons.to_model_targets(
        skeletons.read_bvh(path), settings.skeleton, model, units=settings.units, drop_reference_pose=True
    )


def joints_in_metres(
    joints: np.ndarray, names: Any, weights: Any, settings: Any, model: Any
) -> tuple[np.ndarray, Any, Any, list[str]]:
    """(T, n, 3) joints of a ``.npy`` in metres with Y up, their model joint names and weights, and notes.

    With ``settings.skeleton`` the points are that keypoint skeleton's (mapped to model joints); otherwise the
    joints are model joints (``names``, default the model's first n) and only their units are checked."""
    from smplcore import skeletons

    if settings.skeleton is not None:
        t = skeletons.to_model_targets(joints, settings.skeleton, model, units=settings.units)
        return t.joints, list(t.joint_names), t.joint_weights, list(t.notes)
    known = list(names) if names is not None else list(model.joint_names)[: joints.shape[1]]
    if weights is not None:  # points the convention does not give (weight 0) are not measured
        known = [n if w > 0 else f"unused{i}" for i, (n, w) in enumerate(zip(known, np.ravel(weights)))]
    leg = skeletons.leg_length(joints, known)
    if settings.units is None and not (np.isfinite(leg) and leg > 0):
        return joints, names, weights, []  # no leg to measure: fit_joints refuses a size 10x off the model's
    try:
        u = skeletons.points_units(joints, known, settings.units)
    except ValueError as exc:
        raise ValueError(f"joints: {exc}") from None
    if u.detected and u.name == "m":
        return joints, names, weights, []  # metres: nothing to say
    note = "joints: " + u.message.split("; up axis")[0]  # the joints' axes are kept as given
    if u.name != "m" and settings.units is None:
        note += " (pass --units m if they really are metres)"
    return joints * u.scale, names, weights, [note]
