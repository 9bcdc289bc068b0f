"""Rough T-pose skeletons (metres, y up, z forward, +x = the body's left) per model."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .sizes import _MANO_VERTEX_IDS, _SMPLH_VERTEX_IDS, _SMPLX_VERTEX_IDS


@dataclass
class _Skel:
    names: list
    pos: np.ndarray  # (J, 3)
    parents: np.ndarray  # (J,) -1 for the root
    radius: dict  # joint -> radius of the bone from its parent to it
    skip: set = field(default_factory=set)  # joints whose incoming bone carries no vertices
    leaves: list = field(default_factory=list)  # (owner joint, tip position, radius)
    targets: dict = field(default_factory=dict)  # vertex id -> target position
    head: set = field(default_factory=set)  # joints whose vertices form the face/head
    symmetric: bool = True

    def add(self, name, pos, parent, radius, skip=False):
        self.names.append(name)
        self.pos = np.vstack([self.pos, np.asarray(pos, float)[None]])
        self.parents = np.append(self.parents, parent)
        j = len(self.names) - 1
        self.radius[j] = radius
        if skip:
            self.skip.add(j)
        return j


def _new_skel(symmetric=True) -> _Skel:
    return _Skel(names=[], pos=np.zeros((0, 3)), parents=np.zeros(0, dtype=np.int64), radius={}, symmetric=symmetric)


_M = np.array([-1.0, 1.0, 1.0])  # mirror x


def _body(skel: _Skel, dy: float = 0.0, with_hand_joints: bool = False):
    """The 22 SMPL body joints (pelvis .. wrists) in SMPL order; returns name -> index."""

    def P(x, y, z):
        return np.array([x, y + dy, z])

    idx = {}

    def pair(name, p, parent_l, parent_r, r):
        idx["L_" + name] = skel.add("L_" + name, p, idx[parent_l], r)
        idx["R_" + name] = skel.add("R_" + name, p * _M, idx[parent_r], r)

    idx["pelvis"] = skel.add("pelvis", P(0.0, -0.22, 0.02), -1, 0.0)
    idx["L_hip"] = skel.add("L_hip", P(0.06, -0.31, 0.01), idx["pelvis"], 0.085)
    idx["R_hip"] = skel.add("R_hip", P(-0.06, -0.31, 0.01), idx["pelvis"], 0.085)
    idx["spine1"] = skel.add("spine1", P(0.0, -0.11, -0.01), idx["pelvis"], 0.13)
    pair("knee", P(0.10, -0.68, 0.01), "L_hip", "R_hip", 0.07)
    idx["spine2"] = skel.add("spine2", P(0.0, 0.03, 0.0), idx["spine1"], 0.135)
    pair("ankle", P(0.09, -1.08, -0.03), "L_knee", "R_knee", 0.05)
    idx["spine3"] = skel.add("spine3", P(0.0, 0.09, 0.02), idx["spine2"], 0.14)
    pair("foot", P(0.12, -1.14, 0.09), "L_ankle", "R_ankle", 0.04)
    idx["neck"] = skel.add("neck", P(0.0, 0.29, -0.01), idx["spine3"], 0.10)
    pair("collar", P(0.08, 0.20, 0.0), "spine3", "spine3", 0.08)
    idx["head"] = skel.add("head", P(0.0, 0.36, 0.03), idx["neck"], 0.055)
    pair("shoulder", P(0.17, 0.23, -0.02), "L_collar", "R_collar", 0.06)
    pair("elbow", P(0.43, 0.21, -0.03), "L_shoulder", "R_shoulder", 0.045)
    pair("wrist", P(0.68, 0.21, -0.03), "L_elbow", "R_elbow", 0.035)
    # leaves: head top, toes, heels
    skel.leaves.append((idx["head"], P(0.0, 0.56, 0.01), 0.095))
    for s, sign in (("L_", 1.0), ("R_", -1.0)):
        skel.leaves.append((idx[s + "foot"], P(0.13 * sign, -1.16, 0.17), 0.035))
        skel.leaves.append((idx[s + "ankle"], P(0.085 * sign, -1.15, -0.07), 0.035))
    skel.head.add(idx["head"])
    # named surface points (nose, eyes, ears, toes, heels)
    tg = {
        "nose": P(0.0, 0.44, 0.12),
        "leye": P(0.035, 0.47, 0.10),
        "reye": P(-0.035, 0.47, 0.10),
        "lear": P(0.09, 0.45, 0.0),
        "rear": P(-0.09, 0.45, 0.0),
        "LBigToe": P(0.11, -1.17, 0.20),
        "LSmallToe": P(0.16, -1.17, 0.18),
        "LHeel": P(0.085, -1.18, -0.10),
        "RBigToe": P(-0.11, -1.17, 0.20),
        "RSmallToe": P(-0.16, -1.17, 0.18),
        "RHeel": P(-0.085, -1.18, -0.10),
    }
    return idx, tg


# finger: (knuckle offset from wrist, direction, phalanx lengths)
_FINGERS = {
    "index": ((0.085, 0.0, 0.025), (1.0, 0.0, 0.05), (0.040, 0.025, 0.020, 0.020)),
    "middle": ((0.090, 0.0, 0.005), (1.0, 0.0, 0.0), (0.045, 0.030, 0.022, 0.020)),
    "pinky": ((0.075, 0.0, -0.033), (1.0, 0.0, -0.08), (0.032, 0.020, 0.018, 0.017)),
    "ring": ((0.085, 0.0, -0.015), (1.0, 0.0, -0.04), (0.042, 0.028, 0.020, 0.019)),
    "thumb": ((0.025, -0.015, 0.030), (0.6, -0.2, 0.75), (0.035, 0.030, 0.025, 0.022)),
}
_FINGER_ORDER = ("index", "middle", "pinky", "ring", "thumb")  # SMPL+H / SMPL-X / MANO order


def _hand(skel: _Skel, wrist: int, sign: float, prefix: str):
    """15 finger joints (index, middle, pinky, ring, thumb; 3 each) + 5 fingertip leaves."""
    w = skel.pos[wrist]
    tips = {}
    for fname in _FINGER_ORDER:
        off, d, lengths = _FINGERS[fname]
        off = np.array(off) * np.array([sign, 1, 1])
        d = np.array(d) * np.array([sign, 1, 1])
        d = d / np.linalg.norm(d)
        p = w + off
        parent = wrist
        r = 0.0095 if fname != "thumb" else 0.011
        # the palm bone wrist -> knuckle is wide
        j = skel.add(f"{prefix}{fname}1", p, parent, 0.016)
        for k in (2, 3):
            p = p + d * lengths[k - 2]
            j = skel.add(f"{prefix}{fname}{k}", p, j, r)
        tip = p + d * lengths[2] + d * lengths[3] * 0.2
        skel.leaves.append((j, tip, r * 0.95))
        tips[fname] = tip + d * 0.006
    return tips


def _smpl_skel(scale=1.0) -> _Skel:
    s = _new_skel()
    idx, tg = _body(s)
    for side, sign in (("L_", 1.0), ("R_", -1.0)):
        h = s.add(side + "hand", np.array([0.77 * sign, 0.20, -0.04]), idx[side + "wrist"], 0.03)
        s.leaves.append((h, np.array([0.86 * sign, 0.20, -0.04]), 0.022))
        base = np.array([0.88 * sign, 0.20, -0.04])
        for fname, dz in (
            ("thumb", 0.035),
            ("index", 0.022),
            ("middle", 0.005),
            ("ring", -0.012),
            ("pinky", -0.028),
        ):
            tg[side[0].lower() + fname] = base + np.array([0, 0, dz])
    s.targets = {_SMPLH_VERTEX_IDS[k]: v for k, v in tg.items()}
    _scale(s, scale)
    return s


def _smplh_skel(scale=1.0) -> _Skel:
    s = _new_skel()
    idx, tg = _body(s)
    for side, sign in (("L_", 1.0), ("R_", -1.0)):
        tips = _hand(s, idx[side + "wrist"], sign, side)
        for fname, p in tips.items():
            tg[side[0].lower() + fname] = p
    s.targets = {_SMPLH_VERTEX_IDS[k]: v for k, v in tg.items()}
    _scale(s, scale)
    return s


def _smplx_skel(scale=1.0) -> _Skel:
    s = _new_skel()
    dy = -0.08
    idx, tg = _body(s, dy=dy)
    head = idx["head"]
    jaw = s.add("jaw", np.array([0.0, 0.37 + dy, 0.04]), head, 0.0, skip=True)
    le = s.add("left_eye_smplhf", np.array([0.033, 0.47 + dy, 0.085]), head, 0.0, skip=True)
    re = s.add("right_eye_smplhf", np.array([-0.033, 0.47 + dy, 0.085]), head, 0.0, skip=True)
    s.leaves.append((jaw, np.array([0.0, 0.34 + dy, 0.11]), 0.03))
    s.leaves.append((le, np.array([0.033, 0.47 + dy, 0.105]), 0.013))
    s.leaves.append((re, np.array([-0.033, 0.47 + dy, 0.105]), 0.013))
    s.head.update({jaw, le, re})
    for side, sign in (("L_", 1.0), ("R_", -1.0)):
        tips = _hand(s, idx[side + "wrist"], sign, side)
        for fname, p in tips.items():
            tg[side[0].lower() + fname] = p
    s.targets = {_SMPLX_VERTEX_IDS[k]: v for k, v in tg.items()}
    _scale(s, scale)
    return s


def _mano_skel(scale=1.0) -> _Skel:
    s = _new_skel(symmetric=False)
    w = s.add("wrist", np.array([0.0957, 0.0064, 0.0062]), -1, 0.0)
    s.leaves.append((w, s.pos[w] + np.array([0.035, 0.0, 0.0]), 0.028))  # wrist stub
    tips = _hand(s, w, -1.0, "")
    s.targets = {_MANO_VERTEX_IDS[k]: v for k, v in tips.items()}
    _scale(s, scale)
    return s


def _flame_skel(scale=1.0) -> _Skel:
    s = _new_skel()
    root = s.add("global", np.array([0.0, -0.10, -0.02]), -1, 0.0)
    neck = s.add("neck", np.array([0.0, -0.05, -0.02]), root, 0.05)
    jaw = s.add("jaw", np.array([0.0, -0.02, 0.01]), neck, 0.0, skip=True)
    le = s.add("left_eye", np.array([0.032, 0.03, 0.06]), neck, 0.0, skip=True)
    re = s.add("right_eye", np.array([-0.032, 0.03, 0.06]), neck, 0.0, skip=True)
    s.leaves.append((neck, np.array([0.0, 0.13, 0.0]), 0.085))  # skull
    s.leaves.append((jaw, np.array([0.0, -0.065, 0.085]), 0.032))  # jaw / chin
    s.leaves.append((le, np.array([0.032, 0.03, 0.078]), 0.012))
    s.leaves.append((re, np.array([-0.032, 0.03, 0.078]), 0.012))
    s.head.update({neck, jaw, le, re})
    _scale(s, scale)
    return s


def _scale(s: _Skel, k: float) -> None:
    if k == 1.0:
        return
    s.pos = s.pos * k
    s.radius = {j: r * k for j, r in s.radius.items()}
    s.leaves = [(o, p * k, r * k) for o, p, r in s.leaves]
    s.targets = {v: p * k for v, p in s.targets.items()}
