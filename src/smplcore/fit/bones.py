"""Bone lengths of joint targets against the fitted body's: which target bones the model does not reach.

A skeleton from motion capture is not the body model's: its joints sit elsewhere in the body (a root above
the hips, a neck at the base of the skull) and its proportions may lie outside what the shape space holds
(a CMU torso of 30–33 cm from the root to the neck, against the model's 52 cm or more). The fit cannot
meet such targets with a plausible pose, and its joint limits keep it from folding the spine to try; this
module says which bones are at fault and by how much.

The bones compared are pairs of target joints neighbouring in the model's tree: a joint and the nearest
target joint below it on each branch, and, under a joint that is not a target itself (the pelvis of a
skeleton mapped without it), the shallowest target joint of each branch with the others (both hips and
the neck). A bone's *model length* is the fitted body's distance between the two joints in its rest pose
(its shape, straight spine): what the body's proportions give, before any bending.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.errors import warn

#: A bone is reported when its target and model lengths differ by more than both of these.
RELATIVE = 0.10
ABSOLUTE = 0.02  # metres


class BoneLengthWarning(UserWarning):
    """Target bones that the model's shape space does not reach (see :class:`BoneReport`)."""


@dataclass(frozen=True)
class BoneReport:
    """Target bone lengths against the fitted bodies'.

    Attributes
    ----------
    bones : (m,) ``(joint, joint)`` name pairs.
    target : (B, m) target lengths (metres; NaN where a joint is missing).
    model : (B, m) the fitted bodies' rest-pose lengths between the same joints.
    """

    bones: tuple[tuple[str, str], ...]
    target: np.ndarray
    model: np.ndarray

    @property
    def difference(self) -> np.ndarray:
        """(B, m) target minus model length (metres): negative where the target bone is shorter."""
        return self.target - self.model

    def unreachable(self, relative: float = RELATIVE, absolute: float = ABSOLUTE) -> list[tuple[str, float, float]]:
        """Bones whose median target length (over the bodies) differs from the model's by more than
        ``relative`` and ``absolute`` (metres): ``("a-b", target, model)`` in metres, the largest first."""
        out = []
        for i, (a, b) in enumerate(self.bones):
            target = self.target[:, i]
            if not np.isfinite(target).any():
                continue
            t, m = float(np.nanmedian(target)), float(np.median(self.model[:, i]))
            if abs(t - m) > absolute and abs(t - m) > relative * m:
                out.append((f"{a}-{b}", round(t, 4), round(m, 4)))
        return sorted(out, key=lambda v: -abs(v[1] - v[2]))

    def summary(self, limit: int = 4) -> str:
        found = self.unreachable()
        if not found:
            return f"{len(self.bones)} target bones within {RELATIVE:.0%} of the fitted body's"
        shown = ", ".join(f"{name} {100 * t:.0f} cm (model {100 * m:.0f} cm)" for name, t, m in found[:limit])
        return f"{len(found)} target bones differ from the fitted body's by more than {RELATIVE:.0%}: {shown}"

    def __repr__(self) -> str:
        return f"BoneReport({self.summary()})"


def target_bones(parents: np.ndarray, observed: list[int]) -> list[tuple[int, int]]:
    """Pairs of observed joints (indices into the tree of ``parents``) neighbouring in the tree (see the
    module docstring)."""
    seen = set(observed)
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        if p >= 0:
            children.setdefault(int(p), []).append(j)

    def frontier(j: int, depth: int = 1) -> list[tuple[int, int]]:
        """(joint, depth) of the nearest observed joints at or below ``j``."""
        if j in seen:
            return [(j, depth)]
        return [f for c in children.get(j, []) for f in frontier(c, depth + 1)]

    pairs = []
    for j in range(len(parents)):
        branches = [frontier(c) for c in children.get(j, [])]
        branches = [b for b in branches if b]
        if j in seen:
            pairs += [(j, k) for b in branches for k, _ in b]
        elif len(branches) >= 2:
            firsts = [min(b, key=lambda f: f[1])[0] for b in branches]
            pairs += [(a, b) for i, a in enumerate(firsts) for b in firsts[i + 1 :]]
    return pairs


def bone_report(body: Any, point_ids: np.ndarray, targets: np.ndarray, present: np.ndarray, coeffs: np.ndarray):
    """The :class:`BoneReport` of (B, n, 3) ``targets`` of the fitting points ``point_ids`` (skeleton joints
    are compared, vertex joints left out), ``present`` (B, n), for bodies of shape ``coeffs`` (B, K); None
    when fewer than two skeleton joints are targets."""
    joint_of = {int(p) - body.num_vertices: i for i, p in enumerate(point_ids) if p >= body.num_vertices}
    pairs = target_bones(np.asarray(body.parents), sorted(joint_of))
    if not pairs:
        return None
    names = body.output_joint_names
    a = np.array([joint_of[p] for p, _ in pairs])
    b = np.array([joint_of[q] for _, q in pairs])
    target = np.linalg.norm(targets[:, a] - targets[:, b], axis=-1)
    target = np.where(present[:, a] & present[:, b], target, np.nan)
    rest = body.joint_template + np.einsum("jck,bk->bjc", body.joint_shape, coeffs)  # (B, J, 3)
    model = np.linalg.norm(rest[:, [p for p, _ in pairs]] - rest[:, [q for _, q in pairs]], axis=-1)
    return BoneReport(tuple((names[p], names[q]) for p, q in pairs), target, model)


def warn_unreachable(report: BoneReport | None, what: str) -> None:
    """One :class:`BoneLengthWarning` naming the bones out of reach (nothing when none is)."""
    if report is not None and report.unreachable():
        warn(
            f"{what}: {report.summary()}; the fit keeps the pose within its joint limits and misses those "
            "joints (a skeleton whose joints sit elsewhere in the body? see result.bones)",
            BoneLengthWarning,
        )
