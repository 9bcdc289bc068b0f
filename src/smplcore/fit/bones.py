"""A fit's hook to the bone-length diagnostics: which target bones the model's shape space does not reach.

A skeleton from motion capture is not the body model's: its joints sit elsewhere in the body (a root above
the hips, a neck at the base of the skull) and its proportions may lie outside what the shape space holds
(a CMU torso of 30–33 cm from the root to the neck, against the model's 52 cm or more). The fit cannot
meet such targets with a plausible pose, and its joint limits keep it from folding the spine to try;
:func:`smplcore.skeletons.bone_lengths` says which bones are at fault and by how much, and
:func:`fit_joints <smplcore.fit.fit_joints>` keeps its report as ``result.bones`` and warns
(:class:`BoneLengthWarning`).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from smplcore.errors import warn


class BoneLengthWarning(UserWarning):
    """Target bones that no body of the model's shape space (or not the best common one) reaches."""


def bone_report(model: Any, targets: np.ndarray, present: np.ndarray, names: list[str]) -> Any:
    """:func:`smplcore.skeletons.bone_lengths` of (B, n, 3) ``targets`` of the model joints ``names``, the
    joints not ``present`` (B, n) left out; None when no two targets form a bone."""
    from smplcore.skeletons import bone_lengths

    joints = np.where(present[..., None], targets, np.nan)
    try:
        with warnings.catch_warnings():  # a joint missing in every frame: its bones' lengths are NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            return bone_lengths(model, joints, names)
    except ValueError:  # no bone among the targets (vertex joints alone, a few unrelated joints)
        return None


def warn_unreachable(report: Any, what: str) -> None:
    """One :class:`BoneLengthWarning` naming the bones out of reach of any body, and the rigid bones (a joint
    and its parent) the best common body misses by more than the report's tolerance; nothing when there are
    none. (A bone across joints the pose bends is measured in the postures the targets happen to take: off
    by a few centimetres in a few frames, it is no finding.)"""
    if report is None:
        return
    out = dict(zip(report.bones, report.beyond))
    off = dict(zip(report.bones, report.off))
    rigid = dict(zip(report.bones, ~np.asarray(report.compound, bool)))
    named = [(b, out[b], "out of reach") for b in report.out_of_reach]
    named += [(b, off[b], "off") for b in report.mismatched if not out[b] and rigid[b]]
    if not named:
        return
    named.sort(key=lambda v: -abs(v[1]))
    shown = ", ".join(f"{a}-{b} {100 * d:+.0f} cm ({kind})" for (a, b), d, kind in named[:4])
    warn(
        f"{what}: {len(named)} target bones are not the model's: {shown}; the fit keeps the pose within its "
        "joint limits and misses those joints (print(result.bones) for the table; a skeleton whose joints "
        "sit elsewhere in the body? see smplcore.skeletons)",
        BoneLengthWarning,
    )
