"""Bone-length diagnostics: which of the targets' bones the model's shape space cannot reach, and by how much.

A bone is a pair of target joints: each joint with its nearest targeted ancestor in the model's tree (hip →
knee → ankle, shoulder → elbow → wrist, ...), the hip and shoulder widths, and, where the spine is not
targeted, the midpoint of the hips to the neck (the torso). The target's length is its median over the frames;
for a compound bone (one that spans joints the pose bends: the torso, the widths; marked ``*``) the 90th
percentile, the straightest posture's.
The model's length is a function of the shape coefficients: joints are linear in them (``model.rig``'s
template joints and joint shape directions; a vertex joint, e.g. the nose, reads its vertex), so the length of a
bone along its own direction changes by ``u · D β`` for the bone's unit direction ``u``. Two numbers per bone:

* ``reach``: the range of the length over shapes with ``|β| ≤ 3`` (three standard deviations of the shape
  space): ``L0 ± 3 |Dᵀu|``. A target outside it is out of reach for any body;
* ``fitted``: the length at the one shape that best matches all bones together (least squares, ``|β| ≤ 3``),
  as one body must: a bone can be in reach alone and still off when the others are matched too.

:func:`bone_lengths` is a pure function of (model, targets, joint names); its :class:`BoneReport` prints as a
table and lists the bones off by more than a tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

TORSO = ("hips", "neck")
MAX_SD = 3.0


@dataclass(frozen=True)
class BoneReport:
    """Target bone lengths against what the model's shape space reaches.

    Attributes
    ----------
    bones : (m,) (from, to) joint names; ``"hips"`` is the midpoint of the two hips.
    target : (m,) the targets' bone lengths, metres (median over frames).
    spread : (m,) their interquartile range over frames (0 for a rigid skeleton).
    reach : (m, 2) the model's shortest and longest length with ``|betas| <= 3``.
    fitted : (m,) the model's length at ``betas``, the shape matching all bones best.
    betas : the shape coefficients of ``fitted``.
    compound : (m,) bool, bones that span joints the pose bends (their length is the 90th percentile).
    tolerance : bones whose target is further than this (metres) from ``fitted`` are listed as off.
    """

    bones: tuple[tuple[str, str], ...]
    target: np.ndarray
    spread: np.ndarray
    reach: np.ndarray
    fitted: np.ndarray
    betas: np.ndarray
    compound: np.ndarray
    tolerance: float = 0.02

    @property
    def beyond(self) -> np.ndarray:
        """(m,) metres the target lies outside the reach (positive: longer than reachable, negative: shorter,
        0 inside)."""
        return np.where(self.target > self.reach[:, 1], self.target - self.reach[:, 1],
                        np.where(self.target < self.reach[:, 0], self.target - self.reach[:, 0], 0.0))  # fmt: skip

    @property
    def off(self) -> np.ndarray:
        """(m,) target minus the fitted body's length, metres."""
        return self.target - self.fitted

    @property
    def out_of_reach(self) -> list[tuple[str, str]]:
        """The bones no body of the shape space reaches."""
        return [b for b, d in zip(self.bones, self.beyond) if d != 0.0]

    @property
    def mismatched(self) -> list[tuple[str, str]]:
        """The bones the best common body misses by more than ``tolerance``."""
        return [b for b, d in zip(self.bones, self.off) if abs(d) > self.tolerance]

    @property
    def ok(self) -> bool:
        return not self.out_of_reach and not self.mismatched

    def __str__(self) -> str:
        lines = [f"{'bone':32s} {'target':>8s} {'reach (|betas|<=3)':>19s} {'best body':>9s} {'off':>7s}"]
        for (a, b), t, (lo, hi), f, d, out, c in zip(self.bones, self.target, self.reach, self.fitted, self.off,
                                                     self.beyond, self.compound):  # fmt: skip
            flag = "  OUT OF REACH" if out else ("  off" if abs(d) > self.tolerance else "")
            bone = a + " -> " + b + (" *" if c else "")
            numbers = f"{100 * t:6.1f}cm {100 * lo:8.1f}-{100 * hi:5.1f}cm {100 * f:7.1f}cm {100 * d:+5.1f}cm"
            lines.append(f"{bone:32s} {numbers}{flag}")
        bad = self.out_of_reach
        if bad:
            lines.append("out of reach of any body: " + ", ".join(
                f"{a}->{b} by {100 * abs(d):.1f} cm ({'longer' if d > 0 else 'shorter'})"
                for (a, b), d in zip(self.bones, self.beyond) if d))  # fmt: skip
        off = [(b, d) for b, d in zip(self.bones, self.off) if abs(d) > self.tolerance]
        if off:
            lines.append(f"the best common body misses (> {100 * self.tolerance:.0f} cm): " + ", ".join(
                f"{a}->{b} {100 * d:+.1f} cm" for (a, b), d in off))  # fmt: skip
        if not bad and not off:
            lines.append(f"every bone within {100 * self.tolerance:.0f} cm of one body of the shape space")
        if self.compound.any():
            lines.append("* spans joints the pose bends: the target is its 90th percentile over the frames")
        return "\n".join(lines)


def _rows(model: Any, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Rest joints (n, 3) and their shape directions (n, 3, B) for the named output joints."""
    rig = model.rig
    out_names = list(rig.output_joint_names)
    rows = rig.output_rows()
    nv, nj = rig.num_vertices, rig.num_joints
    base = np.concatenate([rig.template, rig.template_joints], axis=0)  # (V + J, 3)
    dirs = np.concatenate([rig.shapedirs, rig.joint_shapedirs], axis=0)  # (V + J, 3, B)
    if len(out_names) != rows.shape[0] or base.shape[0] != nv + nj:
        raise ValueError("model: its rig's output rows do not match its joints")
    rest, shape = [], []
    for n in names:
        if n not in out_names:
            raise ValueError(f"joint_names: {n!r} is not a joint of this model (model.joint_names)")
        row = rows.getrow(out_names.index(n))
        cols, vals = row.indices, row.data
        rest.append(vals @ base[cols])
        shape.append(np.einsum("k,kcb->cb", vals, dirs[cols]))
    return np.asarray(rest), np.asarray(shape)


def _bones(model: Any, names: list[str]) -> tuple[list[tuple[str, str]], list[bool]]:
    """The bones of the targets and whether each is compound (spans joints the pose bends)."""
    parents = list(model.rig.parents)
    skeleton = list(model.rig.joint_names)[: len(parents)]
    have = set(names)
    out: list[tuple[str, str]] = []
    compound: list[bool] = []
    for n in names:
        if n not in skeleton:
            continue
        j = parents[skeleton.index(n)]
        direct = True
        while j >= 0 and skeleton[j] not in have:
            j, direct = parents[j], False
        if j >= 0:
            out.append((skeleton[j], n))
            compound.append(not direct)
    for pair, bends in ((("left_hip", "right_hip"), False), (("left_shoulder", "right_shoulder"), True)):
        if set(pair) <= have:
            out.append(pair)
            compound.append(bends)
    if {"left_hip", "right_hip", "neck"} <= have and not any(b == "neck" for _, b in out):
        out.append(TORSO)
        compound.append(True)
    return out, compound


def bone_lengths(model: Any, joints: Any, joint_names: Any, tolerance: float = 0.02) -> BoneReport:
    """Compare the bones of ``joints`` with the lengths the model's shape space reaches.

    Parameters
    ----------
    model : a :class:`smplcore.BodyModel` or torch model (its public ``rig``).
    joints : (T, n, 3) or (n, 3) target joint positions, metres (NaN: missing, ignored).
    joint_names : (n,) the model joints they are.
    tolerance : metres a bone may differ from the best common body before it is listed.

    Returns
    -------
    BoneReport (``print(report)`` for a table; ``report.out_of_reach``, ``report.mismatched``).
    """
    names = list(joint_names)
    arr = np.asarray(joints, np.float64)
    arr = arr[None] if arr.ndim == 2 else arr
    if arr.ndim != 3 or arr.shape[1:] != (len(names), 3):
        raise ValueError(f"joints: expected shape (T, {len(names)}, 3), got {np.shape(joints)}")
    bones, compound = _bones(model, names)
    if not bones:
        raise ValueError("joint_names: no two targets form a bone of the model's skeleton")
    used = sorted({n for b in bones for n in b if n != "hips"} | ({"left_hip", "right_hip"} if any(
        "hips" in b for b in bones) else set()))  # fmt: skip
    rest, shape = _rows(model, used)
    index = {n: i for i, n in enumerate(used)}
    pos = {n: arr[:, names.index(n)] for n in used}

    def point(n, table):
        if n == "hips":
            return 0.5 * (table[index["left_hip"]] + table[index["right_hip"]])
        return table[index[n]]

    def target_point(n):
        return 0.5 * (pos["left_hip"] + pos["right_hip"]) if n == "hips" else pos[n]

    lengths = np.stack([np.linalg.norm(target_point(b) - target_point(a), axis=-1) for a, b in bones], axis=1)
    bent = np.asarray(compound, bool)
    target = np.where(bent, np.nanpercentile(lengths, 90, axis=0), np.nanmedian(lengths, axis=0))
    q75, q25 = np.nanpercentile(lengths, [75, 25], axis=0)
    d0 = np.stack([point(b, rest) - point(a, rest) for a, b in bones])  # (m, 3)
    dd = np.stack([point(b, shape) - point(a, shape) for a, b in bones])  # (m, 3, B)
    length0 = np.linalg.norm(d0, axis=-1)
    unit = d0 / np.maximum(length0, 1e-12)[:, None]
    grad = np.einsum("mc,mcb->mb", unit, dd)  # (m, B): dL/dbeta at the template
    span = MAX_SD * np.linalg.norm(grad, axis=1)
    reach = np.stack([length0 - span, length0 + span], axis=1)
    betas = _common_shape(d0, dd, target)
    fitted = np.linalg.norm(d0 + np.einsum("mcb,b->mc", dd, betas), axis=-1)
    return BoneReport(tuple(bones), target, q75 - q25, reach, fitted, betas, bent, tolerance)


def _common_shape(d0: np.ndarray, dd: np.ndarray, target: np.ndarray, iterations: int = 20) -> np.ndarray:
    """The shape (B,) with ``|β| <= 3`` whose bone lengths best match ``target`` (Gauss–Newton on the lengths,
    a small ridge, the norm capped)."""
    betas = np.zeros(dd.shape[-1])
    ok = np.isfinite(target)
    for _ in range(iterations):
        vec = d0 + np.einsum("mcb,b->mc", dd, betas)
        length = np.linalg.norm(vec, axis=-1)
        jac = np.einsum("mc,mcb->mb", vec / np.maximum(length, 1e-12)[:, None], dd)[ok]
        res = (length - target)[ok]
        step = np.linalg.solve(jac.T @ jac + 1e-6 * np.eye(len(betas)), -(jac.T @ res + 1e-6 * betas))
        betas = betas + step
        norm = np.linalg.norm(betas)
        if norm > MAX_SD:
            betas *= MAX_SD / norm
        if np.abs(step).max() < 1e-6:
            break
    return betas
