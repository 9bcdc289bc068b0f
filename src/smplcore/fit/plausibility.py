"""Is a fitted body anatomically possible? Body joints outside their limits, per body, per joint, per axis.

A fit can match its targets and still return a body no one can take (a spine folded to reach a neck that
the shape space cannot place, an elbow bent backwards). :func:`assess` measures, for each body, how far
each body joint's local axis-angle rotation lies outside the anatomical ranges of
:data:`smplcore.fit.priors.JOINT_LIMITS` (the same bounds the fits' limit prior uses; elbows and knees
bending the wrong way are outside them too). A body is *plausible* when no joint exceeds its range by more
than :data:`TOLERANCE` degrees on any axis: the ranges are population averages (AAOS), and a soft limit
prior leaves a joint a little past its bound where the targets pull.

>>> import numpy as np, smplcore
>>> from smplcore.fit.plausibility import assess
>>> model = smplcore.BodyModel(model_type="open")
>>> pose = np.zeros((2, 69))
>>> pose[1, 8 * 3] = np.radians(60)  # spine3 bent forward 60°, 33° past its 26.7°
>>> p = assess(model, pose)
>>> p.plausible.tolist()
[True, False]
>>> p.violations(1)
[('spine3', 'x', 33.3)]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.errors import ShapeError, warn
from smplcore.fit.priors import joint_limits

#: Degrees past a joint's range (any axis) that a plausible body may reach.
TOLERANCE = 10.0
AXES = ("x", "y", "z")


class ImplausibleFitWarning(UserWarning):
    """A fit returned bodies with joints outside their anatomical limits (see :class:`Plausibility`)."""


@dataclass(frozen=True)
class Plausibility:
    """Where B bodies' joints lie outside their anatomical limits.

    Attributes
    ----------
    joint_names : (J,) the body joints assessed (a model's ``body_pose`` joints).
    excess : (B, J, 3) degrees by which each joint's axis-angle component (x, y, z) lies outside its range
        (0 inside).
    angles : (B, J, 3) the components themselves (degrees).
    tolerance : degrees of excess a plausible body may have (:data:`TOLERANCE` by default).
    """

    joint_names: tuple[str, ...]
    excess: np.ndarray
    angles: np.ndarray
    tolerance: float = TOLERANCE

    @property
    def plausible(self) -> np.ndarray:
        """(B,) whether no joint exceeds its range by more than ``tolerance`` degrees."""
        return ~np.any(self.excess > self.tolerance, axis=(1, 2))

    @property
    def worst(self) -> np.ndarray:
        """(B,) the largest excess of each body (degrees)."""
        return self.excess.reshape(len(self.excess), -1).max(axis=1, initial=0.0)

    def violations(self, b: int, tolerance: float | None = None) -> list[tuple[str, str, float]]:
        """Body ``b``'s (joint, axis, degrees past the range) beyond ``tolerance`` (default the
        assessment's), the largest first; degrees rounded to 0.1."""
        tol = self.tolerance if tolerance is None else tolerance
        j, a = np.nonzero(self.excess[b] > tol)
        found = [(self.joint_names[int(i)], AXES[int(k)], round(float(self.excess[b, i, k]), 1)) for i, k in zip(j, a)]
        return sorted(found, key=lambda v: -v[2])

    def joint_counts(self) -> dict[str, int]:
        """How many bodies have each joint outside its range by more than the tolerance (joints that
        never are left out)."""
        over = np.any(self.excess > self.tolerance, axis=2).sum(axis=0)
        return {self.joint_names[j]: int(over[j]) for j in np.flatnonzero(over)}

    def summary(self, limit: int = 3) -> str:
        """One readable line: how many bodies are implausible, which joints, the worst excess."""
        bad = np.flatnonzero(~self.plausible)
        total = len(self.excess)
        if not len(bad):
            return f"{total} of {total} bodies within their joint limits (tolerance {self.tolerance:g}°)"
        counts = sorted(self.joint_counts().items(), key=lambda kv: -kv[1])
        joints = ", ".join(f"{name} in {n}" for name, n in counts[:limit])
        b = int(bad[np.argmax(self.worst[bad])])
        worst = ", ".join(f"{name} {axis} +{deg:g}°" for name, axis, deg in self.violations(b)[:limit])
        return (
            f"{len(bad)} of {total} bodies outside their joint limits by more than {self.tolerance:g}° "
            f"({joints}); worst body {b}: {worst}"
        )

    def __repr__(self) -> str:
        return f"Plausibility({self.summary()})"


def body_joint_names(source: Any) -> tuple[str, ...]:
    """The ``body_pose`` joint names of a model (torch or NumPy), a :class:`~smplcore.model.Rig`, a fit's
    ``FitBody``, or a sequence of names (returned as a tuple)."""
    if isinstance(source, Sequence) and not isinstance(source, str):
        names = tuple(source)
        if not all(isinstance(n, str) for n in names):
            raise TypeError("body_or_joint_names: expected joint names (str), a model or a rig")
        return names
    blocks = getattr(source, "blocks", None)  # a FitBody
    if blocks is not None and hasattr(source, "output_joint_names"):
        for block in blocks:
            if block.name == "body_pose":
                return tuple(source.output_joint_names[block.first_joint : block.first_joint + block.num_joints])
        return ()
    from smplcore.model import Rig

    rig = source if isinstance(source, Rig) else getattr(source, "rig", None)
    if not isinstance(rig, Rig):
        raise TypeError(f"body_or_joint_names: expected a model, a rig or joint names, got {type(source).__name__}")
    for block in rig.pose_blocks:
        if block.name == "body_pose":
            return tuple(rig.joint_names[block.first_joint : block.first_joint + block.num_joints])
    return ()  # a model without body joints (MANO, FLAME)


def assess(body_or_joint_names: Any, body_pose: Any, tolerance: float = TOLERANCE) -> Plausibility:
    """How far each body's joints lie outside their anatomical limits.

    Parameters
    ----------
    body_or_joint_names : a model, its rig, a ``FitBody``, or the (J,) names of the body joints.
    body_pose : (B, 3 J) or (B, J, 3) local axis-angle rotations (radians) of those joints; (3 J,) for one
        body. NumPy or torch.
    tolerance : degrees past a range that a plausible body may reach.
    """
    names = body_joint_names(body_or_joint_names)
    if hasattr(body_pose, "detach"):
        body_pose = body_pose.detach().cpu().numpy()
    theta = np.asarray(body_pose, np.float64)
    if theta.ndim == 1:
        theta = theta[None]
    theta = theta.reshape(len(theta), -1)
    if theta.shape[1] != 3 * len(names):
        raise ShapeError(
            f"body_pose: expected (B, {3 * len(names)}) for {len(names)} body joints, got {tuple(np.shape(body_pose))}"
        )
    theta = theta.reshape(len(theta), len(names), 3)
    lo, hi = joint_limits(list(names))
    excess = np.degrees(np.maximum(lo - theta, 0.0) + np.maximum(theta - hi, 0.0))
    return Plausibility(names, excess, np.degrees(theta), float(tolerance))


def warn_implausible(plausibility: Plausibility, what: str, hint: str = "") -> None:
    """One :class:`ImplausibleFitWarning` naming the implausible bodies and joints (nothing when every body
    is plausible)."""
    if plausibility.plausible.all():
        return
    warn(f"{what}: {plausibility.summary()}{hint}", ImplausibleFitWarning)
