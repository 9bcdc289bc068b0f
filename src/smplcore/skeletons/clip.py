"""A skeleton motion as a BVH file holds it: a joint tree with rest offsets, and per frame local rotations and
translations. :class:`BVHClip` is what :func:`smplcore.skeletons.read_bvh` returns; forward kinematics over
all frames at once gives the world joint positions."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BVHClip:
    """A skeleton motion: a joint tree with rest offsets, and per frame the joints' local rotations and
    translations (the file's units and axes until :func:`smplcore.skeletons.to_metres` converts them).

    Attributes
    ----------
    joint_names : (J,) the joints' names in file order (parents before children).
    parents : (J,) int, each joint's parent index, -1 for the root.
    offsets : (J, 3) rest offsets from the parent (file units).
    channels : (J,) each joint's channel names in file order (``"Xposition"``, ``"Zrotation"``, ...).
    rotations : (T, J, 3, 3) local rotation matrices (the joint's frame in its parent's), from the Euler
        channels in each joint's own order (intrinsic, left to right: ``Zrotation Xrotation Yrotation`` is
        ``Rz @ Rx @ Ry``); identity for joints without rotation channels.
    translations : (T, J, 3) local translations: the offset, with the joint's position channels (if any)
        replacing the offset's components they name (a root's position channels are its absolute position).
    frame_time : seconds per frame (``Frame Time``).
    end_parents : (E,) int, the joint each ``End Site`` hangs from.
    end_offsets : (E, 3) the End Sites' offsets from that joint.
    source : the file (or ``"<string>"``) the clip was read from, for messages.
    units : what one unit of the offsets and translations is: ``"file"`` (as read) or ``"m"`` (converted).
    up : the up axis of the coordinates: ``"file"`` (as read) or ``"y"`` (converted).
    reference_pose : True when frame 0 looked like a reference (T-) pose rather than motion (root rotation
        exactly zero and a jump to frame 1; see :func:`smplcore.skeletons.read_bvh`) and was kept.
    dropped_reference_pose : True when such a frame 0 was dropped on reading.
    """

    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    rotations: np.ndarray
    translations: np.ndarray
    frame_time: float
    end_parents: np.ndarray
    end_offsets: np.ndarray
    source: str = "<string>"
    units: str = "file"
    up: str = "file"
    reference_pose: bool = False
    dropped_reference_pose: bool = False

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def fps(self) -> float:
        """Frames per second, ``1 / frame_time``, rounded to the whole number within 0.01 % of it (a Frame Time
        printed to a few digits: ``0.0083333`` is 120 fps; ``0.008342`` stays 119.875)."""
        rate = 1.0 / self.frame_time
        whole = round(rate)
        return float(whole) if whole > 0 and abs(rate - whole) <= 1e-4 * rate else rate

    @property
    def root_positions(self) -> np.ndarray:
        """(T, 3) the root joint's position per frame."""
        return self.translations[:, 0]

    @property
    def point_names(self) -> tuple[str, ...]:
        """(J + E,) names of :meth:`world_positions` with ``end_sites=True``: the joints, then each End Site
        as ``"<parent>_end"`` (numbered ``_end2``, ... where a joint has several)."""
        taken = set(self.joint_names)
        names = []
        for p in self.end_parents:
            base = f"{self.joint_names[int(p)]}_end"
            name, k = base, 1
            while name in taken:
                k += 1
                name = f"{base}{k}"
            taken.add(name)
            names.append(name)
        return self.joint_names + tuple(names)

    def world_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (T, J, 3, 3) and positions (T, J, 3) of the joints (forward kinematics over all
        frames at once; one step per joint, parents first)."""
        rot = np.empty_like(self.rotations)
        pos = np.empty_like(self.translations)
        for j, p in enumerate(self.parents):
            if p < 0:
                rot[:, j] = self.rotations[:, j]
                pos[:, j] = self.translations[:, j]
            else:
                rot[:, j] = rot[:, p] @ self.rotations[:, j]
                pos[:, j] = pos[:, p] + np.einsum("tij,tj->ti", rot[:, p], self.translations[:, j])
        return rot, pos

    def world_positions(self, end_sites: bool = False) -> np.ndarray:
        """(T, J, 3) world joint positions, or (T, J + E, 3) with the End Sites appended (``point_names``)."""
        rot, pos = self.world_transforms()
        if not end_sites or len(self.end_parents) == 0:
            return pos
        parents = self.end_parents
        ends = pos[:, parents] + np.einsum("teij,ej->tei", rot[:, parents], self.end_offsets)
        return np.concatenate([pos, ends], axis=1)

    def rest_positions(self, end_sites: bool = False) -> np.ndarray:
        """(J, 3) joint positions (or (J + E, 3) with the End Sites) of the rest pose: the offsets chained
        with every rotation the identity, the root at its offset."""
        pos = np.zeros((self.num_joints, 3))
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] if p < 0 else pos[p] + self.offsets[j]
        if not end_sites or len(self.end_parents) == 0:
            return pos
        return np.concatenate([pos, pos[self.end_parents] + self.end_offsets], axis=0)

    def frames(self, index: slice | np.ndarray | list[int]) -> BVHClip:
        """The clip restricted to some frames (a slice or indices)."""
        return dataclasses.replace(self, rotations=self.rotations[index], translations=self.translations[index])

    def without_reference_pose(self) -> BVHClip:
        """The clip without frame 0 if it was detected as a reference pose (else the clip itself)."""
        if not self.reference_pose:
            return self
        return dataclasses.replace(self.frames(slice(1, None)), reference_pose=False, dropped_reference_pose=True)

    def transformed(self, scale: float, axes: np.ndarray, units: str, up: str) -> BVHClip:
        """The clip in other units and axes: lengths times ``scale``, coordinates ``axes @ x`` (a rotation,
        applied to the whole skeleton: offsets, translations and the rotations conjugated, so the rest pose
        stays the rest pose), labelled ``units`` and ``up``."""
        a = np.asarray(axes, np.float64)
        return dataclasses.replace(
            self,
            offsets=scale * self.offsets @ a.T,
            translations=scale * self.translations @ a.T,
            rotations=a @ self.rotations @ a.T,
            end_offsets=scale * self.end_offsets @ a.T,
            units=units,
            up=up,
        )

    def __repr__(self) -> str:
        return (
            f"BVHClip({self.source!r}: {self.num_joints} joints, {self.num_frames} frames at {self.fps:.4g} fps, "
            f"units {self.units!r}, up {self.up!r})"
        )
