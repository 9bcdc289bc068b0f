"""Skeleton maps as data: which points of a real skeleton become which joints of the body model, and how.

A :class:`SkeletonMap` lists :class:`Target`\\ s: a model joint (a name of ``model.joint_names``), the source
point(s) it is made of (one point, or a weighted blend of several), an optional offset (BVH skeletons only:
the point moved in its parent joint's frame, as if the file's ``OFFSET`` were changed) and a fitting weight.
Source points that no target uses are listed in ``dropped`` with the reason. The named maps, and the
measurements behind each choice, are in :mod:`smplcore.skeletons.maps`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Target:
    """One model joint made from the source skeleton.

    Attributes
    ----------
    joint : the model joint (``"left_hip"``, ``"neck"``, ...).
    points : the source point names; several are blended.
    blend : the blend weights of ``points`` (default equal); normalised to sum 1.
    offset : (3,) metres, in the parent frame of ``points[0]`` (Y up, facing +Z in the rest pose): the point is
        moved as if the BVH's ``OFFSET`` were longer by this. BVH skeletons only.
    weight : the joint's weight in the fit (1 for a well-defined joint; lower for points that only
        approximate the model's joint).
    """

    joint: str
    points: tuple[str, ...]
    blend: tuple[float, ...] = ()
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    weight: float = 1.0

    @property
    def blend_weights(self) -> np.ndarray:
        w = np.asarray(self.blend if self.blend else [1.0] * len(self.points), np.float64)
        return w / w.sum()


@dataclass(frozen=True)
class SkeletonMap:
    """A real skeleton's points mapped onto the SMPL family's joint names.

    Attributes
    ----------
    name : the key (``"cmu_mb"``).
    title : what the skeleton is, in words.
    kind : ``"bvh"`` (a joint tree with rotations: offsets allowed) or ``"points"`` (3D keypoints).
    points : the skeleton's point names, in order (for ``"points"``: the order of an array's K points; for
        ``"bvh"``: the joints the map expects, End Sites as ``"<joint>_end"``).
    targets : the model joints made from them.
    dropped : (point, reason) for points no target uses.
    up : the usual up axis of its files (detection decides; this is reported when it agrees).
    units : the usual units of its files (a key of :data:`~smplcore.skeletons.units.UNIT_SCALES`), or None.
    """

    name: str
    title: str
    kind: str
    points: tuple[str, ...]
    targets: tuple[Target, ...]
    dropped: tuple[tuple[str, str], ...] = ()
    up: str = "y"
    units: str | None = None
    aliases: tuple[str, ...] = field(default=())

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The model joints of the targets, in order."""
        return tuple(t.joint for t in self.targets)

    @property
    def weights(self) -> np.ndarray:
        return np.asarray([t.weight for t in self.targets], np.float64)

    def source_of(self, joint: str) -> Target | None:
        return next((t for t in self.targets if t.joint == joint), None)

    def resolve(self, model: Any) -> SkeletonMap:
        """The map restricted to the joints ``model`` has (``model.joint_names``); a map that keeps no hip,
        knee or ankle is refused."""
        have = set(model.joint_names)
        kept = tuple(t for t in self.targets if t.joint in have)
        lost = tuple((", ".join(t.points), f"the model has no joint {t.joint!r}") for t in self.targets
                     if t.joint not in have)  # fmt: skip
        if len(kept) < 3:
            raise ValueError(f"skeleton {self.name}: only {len(kept)} of its targets are joints of this model")
        return SkeletonMap(self.name, self.title, self.kind, self.points, kept, self.dropped + lost, self.up,
                           self.units, self.aliases)  # fmt: skip

    def describe(self) -> str:
        """The map as text: one line per target, then the dropped points."""
        lines = [f"{self.name}: {self.title}"]
        for t in self.targets:
            src = (
                " + ".join(f"{b:.2g} {p}" for p, b in zip(t.points, t.blend_weights))
                if len(t.points) > 1
                else t.points[0]
            )
            off = "" if not any(t.offset) else f" moved {tuple(round(v, 3) for v in t.offset)} m"
            lines.append(f"  {t.joint:15s} <- {src}{off} (weight {t.weight:g})")
        for point, why in self.dropped:
            lines.append(f"  dropped {point}: {why}")
        return "\n".join(lines)


def sided(joint: str, left: str | Sequence[str], right: str | Sequence[str], **kw: Any) -> tuple[Target, Target]:
    """The left and right targets of ``joint`` (``"hip"`` -> ``left_hip`` and ``right_hip``); mirrored offsets
    (x negated on the right)."""
    offset = kw.pop("offset", (0.0, 0.0, 0.0))
    lp = (left,) if isinstance(left, str) else tuple(left)
    rp = (right,) if isinstance(right, str) else tuple(right)
    mirrored = (-offset[0], offset[1], offset[2])
    return (Target(f"left_{joint}", lp, offset=tuple(offset), **kw),
            Target(f"right_{joint}", rp, offset=mirrored, **kw))  # fmt: skip


def lr(pattern: str) -> tuple[str, str]:
    """``"{s}Shldr"`` with s = l / r, ``"{S}Arm"`` with S = Left / Right, ``"{x}_hip"`` with x = left / right."""
    return (pattern.format(s="l", S="Left", x="left", L="L"), pattern.format(s="r", S="Right", x="right", L="R"))


def drop_rest(points: Iterable[str], targets: Iterable[Target], reasons: dict[str, str],
              default: str) -> tuple[tuple[str, str], ...]:  # fmt: skip
    """(point, reason) for every point no target uses: its reason in ``reasons`` or ``default``."""
    used = {p for t in targets for p in t.points}
    return tuple((p, reasons.get(p, default)) for p in points if p not in used)
