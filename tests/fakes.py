"""Structurally exact fake *official* body-model files, built from seeded random data.

The official SMPL / SMPL+H / SMPL-X / MANO / FLAME files cannot be downloaded in tests, so this
module writes stand-ins with the real file names, key names, shapes, dtypes and container
formats:

* legacy pickles (SMPL, MANO, FLAME, SMPL-X ``.pkl``, the raw SMPL+H ``.pkl``) are written the
  way Python 2 wrote them: pickle protocol 2, byte strings (dict keys, array data) as Python 2
  ``str`` opcodes (``BINSTRING`` / ``SHORT_BINSTRING``, so loading needs ``encoding="latin1"``
  exactly like the real files), and the legacy global names ``numpy.core.multiarray`` and
  ``scipy.sparse.csc`` instead of today's ``numpy._core.multiarray`` / ``scipy.sparse._csc``;
* ``shapedirs`` is a chumpy ``Ch`` where the official file has one, ``J_regressor`` a
  ``scipy.sparse.csc_matrix`` where the official file has one;
* ``.npz`` files are plain ``numpy.savez`` archives (object arrays where the real ones have them).

The contents are random but *valid*: a rough T-pose skeleton at human scale (metres, y up,
z forward, +x = the body's left), vertices scattered around its bones (real vertex counts, so the
fixed vertex ids smplx uses for extra joints exist; those ids are moved onto plausible spots --
nose, eyes, ears, toes, heels, fingertips), skinning weights on 1-4 nearby joints summing to 1,
joint regressors with non-negative rows summing to 1 over 10-40 vertices near each joint, closed
triangle lists using every vertex, small blend shapes of realistic magnitude, valid landmark
faces with positive barycentric coordinates.

Everything is deterministic in ``seed``; the same ``(model, gender, seed)`` gives the same numbers
whatever the container (``.pkl`` vs ``.npz``) or file name, so readers of both can be compared.
Only numpy and scipy are needed at import time; chumpy is imported when a ``Ch`` is written.

Facts about the real files that could not be checked here (only their structure as read by
smplx 0.1.28 is certain) and were chosen as follows:

* dtypes: ``f`` uint32 and ``kintree_table`` int64 with ``4294967295`` as the root's parent in
  every file; landmark face indices int64 in SMPL-X, uint32 in the FLAME embeddings; all float
  data float64 (including the big SMPL-X ``.npz``);
* the SMPL-X files have no ``J``; their ``.npz`` has the stray ``allow_pickle`` entry;
  ``joint2num``/``part2num`` contents are made up (names -> ints);
* old scipy's ``csc_matrix`` pickled state is taken to be today's (``_shape``, ``maxprint``,
  ``indices``, ``indptr``, ``data``); chumpy ``Ch`` state is whatever chumpy-fixed writes;
* ``pose_training_info`` contents are made up; the SMPL+H / AMASS ``.npz`` string entries
  (``bs_style``, ``bs_type``) are 0-d unicode arrays;
* the FLAME dynamic embedding holds ndarrays (the real one may hold lists of arrays);
* MANO_LEFT's faces are taken to be the right hand's with reversed winding.

Public API (all return :class:`pathlib.Path`):

``write_smpl``, ``write_smplh``, ``write_smplx``, ``write_kid_template``,
``write_smplx_kid_template``, ``write_mano``, ``write_flame``, ``write_flame_landmarks``,
``write_all`` (returns a dict of paths).
"""

from __future__ import annotations

import os
import pickle
import shutil
import struct
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

__all__ = [
    "FLAME_FACES",
    "MANO_FACES",
    "SMPLX_FACES",
    "SMPL_FACES",
    "dump_legacy_pickle",
    "write_all",
    "write_flame",
    "write_flame_landmarks",
    "write_kid_template",
    "write_mano",
    "write_smpl",
    "write_smplh",
    "write_smpl_uv_obj",
    "write_smplx",
    "write_smplx_kid_template",
]

# Real sizes.
SMPL_VERTS, SMPL_FACES = 6890, 13776
SMPLX_VERTS, SMPLX_FACES = 10475, 20908
SMPLX_UVS = 11313
SMPL_UVS = 7576
MANO_VERTS, MANO_FACES = 778, 1538
FLAME_VERTS, FLAME_FACES = 5023, 9976
HAND_COEFF_ROWS = 1554
ROOT_PARENT = 4294967295  # what the official kintree_table stores as the root's parent

# Vertex ids smplx uses for extra joints (facts about the real meshes' topology).
_SMPLH_VERTEX_IDS = {
    "nose": 332,
    "reye": 6260,
    "leye": 2800,
    "rear": 4071,
    "lear": 583,
    "rthumb": 6191,
    "rindex": 5782,
    "rmiddle": 5905,
    "rring": 6016,
    "rpinky": 6133,
    "lthumb": 2746,
    "lindex": 2319,
    "lmiddle": 2445,
    "lring": 2556,
    "lpinky": 2673,
    "LBigToe": 3216,
    "LSmallToe": 3226,
    "LHeel": 3387,
    "RBigToe": 6617,
    "RSmallToe": 6624,
    "RHeel": 6787,
}
_SMPLX_VERTEX_IDS = {
    "nose": 9120,
    "reye": 9929,
    "leye": 9448,
    "rear": 616,
    "lear": 6,
    "rthumb": 8079,
    "rindex": 7669,
    "rmiddle": 7794,
    "rring": 7905,
    "rpinky": 8022,
    "lthumb": 5361,
    "lindex": 4933,
    "lmiddle": 5058,
    "lring": 5169,
    "lpinky": 5286,
    "LBigToe": 5770,
    "LSmallToe": 5780,
    "LHeel": 8846,
    "RBigToe": 8463,
    "RSmallToe": 8474,
    "RHeel": 8635,
}
_MANO_VERTEX_IDS = {"thumb": 744, "index": 320, "middle": 443, "ring": 554, "pinky": 671}

_GENDER_CODE = {"neutral": 0, "male": 1, "female": 2}
_GENDER_SCALE = {"neutral": 1.0, "male": 1.05, "female": 0.95}
_MODEL_CODE = {"smpl": 11, "smplh": 12, "smplx": 13, "mano": 14, "flame": 15}


# --------------------------------------------------------------------------------------------
# Legacy (Python 2 style) pickling
# --------------------------------------------------------------------------------------------


def _legacy_global(module: str, name: str) -> tuple[str, str]:
    """Map today's module paths to those in files written with old numpy / scipy / Python 2."""
    if module == "numpy._core" or module.startswith("numpy._core."):
        module = "numpy.core" + module[len("numpy._core") :]
    elif module.startswith("scipy.sparse._") and name.endswith("_matrix"):
        module = "scipy.sparse." + module[len("scipy.sparse._") :]
    if module == "builtins":
        module = "__builtin__"
    return module, name


class _LegacyPickler(pickle._Pickler):  # the pure-Python pickler, so opcodes can be chosen
    """Pickler writing what Python 2 (protocol 2) / old numpy and scipy wrote.

    With ``py2_strings`` every ``bytes`` and every ASCII ``str`` becomes a Python 2 ``str``
    (``SHORT_BINSTRING`` / ``BINSTRING``); non-ASCII text stays ``unicode`` (``BINUNICODE``).
    Global names are mapped with :func:`_legacy_global`.
    """

    dispatch = pickle._Pickler.dispatch.copy()

    def __init__(self, file, protocol: int = 2, py2_strings: bool = True):
        super().__init__(file, protocol=protocol, fix_imports=True)
        self.py2_strings = py2_strings and protocol <= 2

    def _write_py2_str(self, data: bytes, obj) -> None:
        n = len(data)
        if n < 256:
            self.write(pickle.SHORT_BINSTRING + bytes([n]))
        else:
            self.write(pickle.BINSTRING + struct.pack("<i", n))
        self.write(data)
        self.memoize(obj)

    def save_bytes(self, obj):
        if self.py2_strings:
            self._write_py2_str(obj, obj)
        else:
            pickle._Pickler.save_bytes(self, obj)

    def save_str(self, obj):
        if self.py2_strings and obj.isascii():
            self._write_py2_str(obj.encode("ascii"), obj)
        else:
            pickle._Pickler.save_str(self, obj)

    dispatch[bytes] = save_bytes
    dispatch[str] = save_str

    def save_global(self, obj, name=None):
        if name is None:
            name = getattr(obj, "__qualname__", None) or obj.__name__
        module = pickle.whichmodule(obj, name)
        module, name = _legacy_global(module, name)
        if self.proto >= 4:
            self.save(module)
            self.save(name)
            self.write(pickle.STACK_GLOBAL)
        else:
            self.write(pickle.GLOBAL + module.encode("ascii") + b"\n" + name.encode("ascii") + b"\n")
        self.memoize(obj)


def dump_legacy_pickle(obj, path, protocol: int = 2, py2_strings: bool = True) -> Path:
    """Write ``obj`` to ``path`` as an official (Python 2 era) pickle would be written."""
    path = Path(path)
    with open(path, "wb") as fh:
        _LegacyPickler(fh, protocol=protocol, py2_strings=py2_strings).dump(obj)
    return path


def _save_legacy_npy_object(obj, path) -> Path:
    """A ``.npy`` holding a 0-d object array (e.g. a dict), as ``numpy.save`` under Python 2."""
    arr = np.empty((), dtype=object)
    arr[()] = obj
    path = Path(path)
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(fh, {"descr": "|O", "fortran_order": False, "shape": ()})
        _LegacyPickler(fh, protocol=2, py2_strings=True).dump(arr)
    return path


def _ch(arr):
    import chumpy  # chumpy-fixed; only needed when writing files that hold a Ch

    return chumpy.Ch(np.asarray(arr))


def _object0(obj) -> np.ndarray:
    arr = np.empty((), dtype=object)
    arr[()] = obj
    return arr


# --------------------------------------------------------------------------------------------
# Skeletons (rough T-poses, metres)
# --------------------------------------------------------------------------------------------


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


# --------------------------------------------------------------------------------------------
# Mesh generation
# --------------------------------------------------------------------------------------------


def _perp_frame(d):
    a = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(d, a)
    u /= np.linalg.norm(u)
    return u, np.cross(d, u)


def _bones(s: _Skel):
    """List of (owner, end joint or -1, a, b, radius, leaf)."""
    out = []
    for j in range(1, len(s.names)):
        if j in s.skip:
            continue
        p = int(s.parents[j])
        out.append((p, j, s.pos[p], s.pos[j], s.radius[j], False))
    for o, tip, r in s.leaves:
        out.append((o, -1, s.pos[o], np.asarray(tip, float), r, True))
    return out


def _key(a, b):
    return tuple(np.round(np.concatenate([a, b]), 6))


def _sample_bone(rng, a, b, r, n, leaf):
    axis = b - a
    d = axis / np.linalg.norm(axis)
    u, w = _perp_frame(d)
    t = rng.uniform(0.0, 1.0, n)
    th = rng.uniform(0.0, 2 * np.pi, n)
    rad = r * rng.uniform(0.85, 1.1, n)
    if leaf:
        rad = rad * np.sqrt(np.clip(1.0 - t**2, 0.04, 1.0))
    off = rad[:, None] * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * w)
    return a + t[:, None] * axis + off, t


@dataclass
class _Mesh:
    v: np.ndarray  # (V, 3)
    bone: np.ndarray  # (V,) bone index
    t: np.ndarray  # (V,) position along the bone
    rnd: np.ndarray  # (V, 3) per-vertex random factors (shared by mirror pairs)
    sym: np.ndarray  # (V,) mirror vertex (self for unpaired)
    bones: list


def _make_mesh(rng, s: _Skel, n_verts: int) -> _Mesh:
    bones = _bones(s)
    nb = len(bones)
    # mirror partner of every bone
    mirror = np.arange(nb)
    if s.symmetric:
        keys = {_key(a, b): i for i, (_, _, a, b, _, _) in enumerate(bones)}
        for i, (_, _, a, b, _, _) in enumerate(bones):
            mirror[i] = keys.get(_key(a * _M, b * _M), i)
    # vertex budget ~ lateral area, at least 8 per bone
    area = np.array([np.linalg.norm(b - a) * r + 0.5 * r * r for _, _, a, b, r, _ in bones])
    base = np.full(nb, 8)
    extra = (n_verts - base.sum()) * area / area.sum()
    counts = base + np.floor(extra).astype(int)
    # keep mirror pairs equal (take the smaller) and fill the rest on self-mirrored bones
    for i in range(nb):
        counts[i] = counts[mirror[i]] = min(counts[i], counts[mirror[i]])
    centre = [i for i in range(nb) if mirror[i] == i]
    deficit = n_verts - counts.sum()
    k = 0
    while deficit > 0:
        counts[centre[k % len(centre)]] += 1
        deficit -= 1
        k += 1
    assert counts.sum() == n_verts

    vs, bidx, ts, rnds, syms = [], [], [], [], []
    start = 0
    done = set()
    for i in range(nb):
        if i in done:
            continue
        _, _, a, b, r, leaf = bones[i]
        n = counts[i]
        j = mirror[i]
        if j != i:  # pair: sample bone i, mirror into bone j
            p, t = _sample_bone(rng, a, b, r, n, leaf)
            q = rng.uniform(0.5, 1.5, (n, 3))
            vs += [p, p * _M]
            bidx += [np.full(n, i), np.full(n, j)]
            ts += [t, t]
            rnds += [q, q]
            syms += [np.arange(n) + start + n, np.arange(n) + start]
            start += 2 * n
            done.update({i, j})
        elif s.symmetric:  # on the mid-plane: half, its mirror, maybe one vertex on x = 0
            m = n // 2
            p, t = _sample_bone(rng, a, b, r, m, leaf)
            p[:, 0] = np.abs(p[:, 0])
            q = rng.uniform(0.5, 1.5, (m, 3))
            parts_v, parts_t, parts_q = [p, p * _M], [t, t], [q, q]
            parts_s = [np.arange(m) + start + m, np.arange(m) + start]
            if n % 2:
                d = (b - a) / np.linalg.norm(b - a)
                e = np.cross(d, np.array([1.0, 0.0, 0.0]))
                e /= np.linalg.norm(e)
                tm = rng.uniform(0.0, 1.0)
                parts_v.append((a + tm * (b - a) + r * e)[None])
                parts_t.append(np.array([tm]))
                parts_q.append(rng.uniform(0.5, 1.5, (1, 3)))
                parts_s.append(np.array([start + 2 * m]))
            vs += parts_v
            ts += parts_t
            rnds += parts_q
            syms += parts_s
            bidx.append(np.full(n, i))
            start += n
            done.add(i)
        else:
            p, t = _sample_bone(rng, a, b, r, n, leaf)
            vs.append(p)
            ts.append(t)
            rnds.append(rng.uniform(0.5, 1.5, (n, 3)))
            syms.append(np.arange(n) + start)
            bidx.append(np.full(n, i))
            start += n
            done.add(i)
    mesh = _Mesh(
        v=np.concatenate(vs),
        bone=np.concatenate(bidx),
        t=np.concatenate(ts),
        rnd=np.concatenate(rnds),
        sym=np.concatenate(syms),
        bones=bones,
    )
    assert len(mesh.v) == n_verts
    _place_named(mesh, s.targets)
    return mesh


def _place_named(mesh: _Mesh, targets: dict) -> None:
    """Permute vertices so that each named vertex id sits nearest its target point."""
    n = len(mesh.v)
    perm = np.arange(n)
    fixed = np.zeros(n, bool)
    for vid, target in sorted(targets.items()):
        d = np.linalg.norm(mesh.v[perm] - np.asarray(target), axis=1)
        d[fixed] = np.inf
        src = int(np.argmin(d))
        perm[[vid, src]] = perm[[src, vid]]
        fixed[vid] = True
    inv = np.empty(n, dtype=np.int64)
    inv[perm] = np.arange(n)
    mesh.v, mesh.bone, mesh.t, mesh.rnd = mesh.v[perm], mesh.bone[perm], mesh.t[perm], mesh.rnd[perm]
    mesh.sym = inv[mesh.sym[perm]]


def _weights(mesh: _Mesh, s: _Skel) -> np.ndarray:
    n, nj = len(mesh.v), len(s.names)
    owner = np.array([b[0] for b in mesh.bones])[mesh.bone]
    end = np.array([b[1] for b in mesh.bones])[mesh.bone]
    par = s.parents[owner]
    gpar = np.where(par >= 0, s.parents[np.maximum(par, 0)], -1)
    t = mesh.t
    rows = np.arange(n)
    w = np.zeros((n, nj))
    w[rows, owner] = 1.0
    near_end = 0.6 * np.clip((t - 0.65) / 0.35, 0, 1) ** 2 * mesh.rnd[:, 0]
    ok = end >= 0
    w[rows[ok], end[ok]] += near_end[ok]
    near_start = 0.6 * np.clip((0.35 - t) / 0.35, 0, 1) ** 2 * mesh.rnd[:, 1]
    ok = par >= 0
    w[rows[ok], par[ok]] += near_start[ok]
    ok = gpar >= 0
    w[rows[ok], gpar[ok]] += 0.15 * near_start[ok] * mesh.rnd[ok, 2]
    return w / w.sum(axis=1, keepdims=True)


def _regressor(rng, v, joints) -> np.ndarray:
    reg = np.zeros((len(joints), len(v)))
    for j, p in enumerate(joints):
        k = int(rng.integers(10, 41))
        d = np.linalg.norm(v - p, axis=1)
        near = np.argpartition(d, k)[:k]
        w = rng.uniform(0.2, 1.0, k)
        reg[j, near] = w / w.sum()
    return reg


def _faces(mesh: _Mesh, n_faces: int) -> np.ndarray:
    """Triangles over neighbours in (bone, t) order: every vertex used, no repeated index."""
    order = np.lexsort((mesh.t, mesh.bone))
    n = len(order)
    i = np.arange(n - 2)
    strip = np.stack([order[i], order[i + 1], order[i + 2]], 1)
    strip[1::2] = strip[1::2, [0, 2, 1]]  # alternate winding like a triangle strip
    i = np.arange(n - 3)
    more = np.concatenate(
        [
            np.stack([order[i], order[i + 1], order[i + 3]], 1),
            np.stack([order[i], order[i + 2], order[i + 3]], 1),
        ]
    )
    f = np.concatenate([strip, more])[:n_faces]
    assert len(f) == n_faces
    return f


def _blend_shapes(rng, mesh: _Mesh, n_comp: int, scale: float, centre, first_is_height=True):
    """(V, 3, n_comp) smooth-per-bone directions plus noise, magnitudes decaying like PCA."""
    n = len(mesh.v)
    nb = len(mesh.bones)
    mags = scale / np.sqrt(1.0 + np.arange(n_comp))
    per_bone = rng.normal(size=(nb, 3, n_comp))
    out = per_bone[mesh.bone]
    out += 0.3 * rng.normal(size=(n, 3, n_comp))
    out *= mags
    if first_is_height and n_comp:
        out[:, :, 0] = (mesh.v - centre) * np.array([0.012, 0.035, 0.012])
    return out


def _posedirs(rng, mesh: _Mesh, s: _Skel, weights: np.ndarray, scale: float) -> np.ndarray:
    """(V, 3, 9*(J-1)): vertices react to the joints that skin them (and their children)."""
    n, nj = weights.shape
    infl = weights > 0
    owner = np.array([b[0] for b in mesh.bones])[mesh.bone]
    child_of = s.parents[:, None] == np.arange(nj)[None, :]  # [c, p]: c is a child of p
    infl |= child_of.T[owner]
    vi, fi = np.nonzero(np.repeat(infl[:, 1:], 9, axis=1))  # (vertex, feature) pairs
    pd = np.zeros((n, 3, 9 * (nj - 1)))
    pd[vi, :, fi] = scale * rng.standard_normal((len(vi), 3))
    return pd


def _hand_pca(seed: int):
    """Right-hand PCA (components with std-scaled rows, mean, training coefficients)."""
    rng = np.random.default_rng([seed, 777])
    q, _ = np.linalg.qr(rng.normal(size=(45, 45)))
    std = 0.9 * np.exp(-np.arange(45) / 9.0) + 0.05
    comps = q.T * std[:, None]
    mean = np.tile(np.array([0.02, 0.05, 0.25]), 15) + 0.05 * rng.normal(size=45)
    coeffs = rng.normal(size=(HAND_COEFF_ROWS, 45))
    return comps, mean, coeffs


_HAND_MIRROR = np.tile(np.array([1.0, -1.0, -1.0]), 15)  # axis-angle of a mirrored joint


def _left_from_right_pca(comps, mean, coeffs):
    return comps * _HAND_MIRROR, mean * _HAND_MIRROR, coeffs.copy()


def _kintree(parents) -> np.ndarray:
    p = np.asarray(parents, dtype=np.int64).copy()
    p[0] = ROOT_PARENT
    return np.stack([p, np.arange(len(p), dtype=np.int64)])


def _rng(model, gender, seed, *extra):
    return np.random.default_rng([seed, _MODEL_CODE[model], _GENDER_CODE.get(gender, 9), *extra])


def _norm_gender(gender: str) -> str:
    g = gender.lower()
    if g in ("generic", "neutral"):
        return "neutral"
    if g in ("m", "male"):
        return "male"
    if g in ("f", "female"):
        return "female"
    raise ValueError(f"unknown gender {gender!r}")


# While write_all runs, _core results are kept here (same model/gender/seed => same numbers).
_CACHE: dict | None = None


def _core(
    model: str,
    gender: str,
    seed: int,
    n_verts: int,
    n_faces: int,
    skel: _Skel,
    n_shape: int,
    shape_scale: float,
    pose_scale: float,
):
    """Mesh, skinning, regressor, faces, blend shapes; returns (rng, mesh, dict of arrays).

    Callers may replace entries of the dict but must not modify its arrays in place."""
    key = (model, gender, seed)
    if _CACHE is not None and key in _CACHE:
        state, mesh, d = _CACHE[key]
        rng = np.random.default_rng()
        rng.bit_generator.state = state
        return rng, mesh, dict(d)
    rng, mesh, d = _core_uncached(model, gender, seed, n_verts, n_faces, skel, n_shape, shape_scale, pose_scale)
    if _CACHE is not None:
        _CACHE[key] = (rng.bit_generator.state, mesh, dict(d))
    return rng, mesh, d


def _core_uncached(model, gender, seed, n_verts, n_faces, skel, n_shape, shape_scale, pose_scale):
    rng = _rng(model, gender, seed)
    mesh = _make_mesh(rng, skel, n_verts)
    w = _weights(mesh, skel)
    reg = _regressor(rng, mesh.v, skel.pos)
    f = _faces(mesh, n_faces)
    centre = mesh.v.mean(axis=0)
    shapedirs = _blend_shapes(rng, mesh, n_shape, shape_scale, centre)
    posedirs = _posedirs(rng, mesh, skel, w, pose_scale)
    return (
        rng,
        mesh,
        {
            "v_template": mesh.v.astype(np.float64),
            "f": f.astype(np.uint32),
            "weights": w,
            "J_regressor": reg,
            "kintree_table": _kintree(skel.parents),
            "shapedirs": shapedirs,
            "posedirs": posedirs,
            "J": reg @ mesh.v,
        },
    )


def _head_faces(mesh: _Mesh, skel: _Skel, f: np.ndarray, front: bool):
    owner = np.array([b[0] for b in mesh.bones])[mesh.bone]
    head_v = np.isin(owner, sorted(skel.head))
    ok = head_v[f].all(axis=1)
    if front:
        z = mesh.v[f][:, :, 2].mean(axis=1)
        ok &= z > np.median(mesh.v[head_v, 2])
    ids = np.flatnonzero(ok)
    assert len(ids) > 100, "too few head faces for landmarks"
    return ids


def _bary(rng, shape):
    return rng.dirichlet([3.0, 3.0, 3.0], size=shape)


def _expression(rng, mesh: _Mesh, skel: _Skel, n_comp: int, scale: float) -> np.ndarray:
    owner = np.array([b[0] for b in mesh.bones])[mesh.bone]
    head_v = np.isin(owner, sorted(skel.head)).astype(float)
    z = mesh.v[:, 2]
    front = np.clip((z - np.median(z[head_v > 0])) / 0.05, 0.0, 1.0) * head_v
    mags = scale / np.sqrt(1.0 + np.arange(n_comp))
    e = rng.normal(size=(len(mesh.v), 3, n_comp)) * mags
    return e * front[:, None, None]


# --------------------------------------------------------------------------------------------
# Writers
# --------------------------------------------------------------------------------------------


def _npz(path: Path, data: dict) -> Path:
    """An uncompressed ``.npz`` like ``numpy.savez`` writes, but any key allowed (the official
    SMPL-X archives hold an ``allow_pickle`` entry, which today's ``savez`` would swallow)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for key, val in data.items():
            with zf.open(key + ".npy", "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asanyarray(val), allow_pickle=True)
    return path


def _dense(x):
    return x.toarray() if sp.issparse(x) else np.asarray(x)


def _smpl_arrays(gender: str, seed: int, n_shape: int):
    g = _norm_gender(gender)
    skel = _smpl_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("smpl", g, seed, SMPL_VERTS, SMPL_FACES, skel, 300, 0.02, 2e-3)
    d["shapedirs"] = np.ascontiguousarray(d["shapedirs"][:, :, :n_shape])
    w_prior = d["weights"] * rng.uniform(0.8, 1.2, d["weights"].shape)
    w_prior /= w_prior.sum(axis=1, keepdims=True)
    d["weights_prior"] = w_prior
    d["J_regressor_prior"] = _regressor(rng, mesh.v, skel.pos)
    d["vert_sym_idxs"] = mesh.sym.astype(np.int64)
    d["bs_style"] = "lbs"
    d["bs_type"] = "lrotmin"
    return d


def write_smpl(
    dirpath,
    gender: str = "neutral",
    version: str = "1.1",
    fmt: str = "pkl",
    seed: int = 0,
    official_name: bool = False,
) -> Path:
    """Fake SMPL model (6890 vertices, 24 joints, 207 pose-corrective features).

    ``version="1.0"``: 10 shape components, ``"1.1"``: 300. ``fmt="pkl"``: the official
    Python-2 pickle (``shapedirs`` a chumpy ``Ch``, ``J_regressor``/``J_regressor_prior``
    ``scipy.sparse.csc_matrix``, ``pose_training_info`` a dict, ``bs_style``/``bs_type`` str).
    ``fmt="npz"``: the same arrays, chumpy-free, regressors dense, no ``pose_training_info``
    (loads without ``allow_pickle``).

    File name: ``SMPL_{GENDER}.{pkl|npz}`` (what smplx looks for), or with ``official_name``
    the download's name: v1.0 ``basicModel_f_lbs_10_207_0_v1.0.0.pkl`` /
    ``basicmodel_m_lbs_10_207_0_v1.0.0.pkl`` / ``basicModel_neutral_lbs_10_207_0_v1.0.0.pkl``
    (the neutral one ships with SMPLify), v1.1 ``basicModel_f_lbs_10_207_0_v1.1.0.pkl`` /
    ``basicmodel_m_lbs_10_207_0_v1.1.0.pkl`` / ``basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl``
    (the mixed case is as distributed, as far as known: readers should match names
    case-insensitively).
    """
    if version not in ("1.0", "1.1"):
        raise ValueError("version must be '1.0' or '1.1'")
    g = _norm_gender(gender)
    d = _smpl_arrays(g, seed, 10 if version == "1.0" else 300)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    if official_name:
        letter = {"female": "f", "male": "m", "neutral": "neutral"}[g]
        stem = {
            "1.0": {"f": "basicModel", "m": "basicmodel", "neutral": "basicModel"},
            "1.1": {"f": "basicModel", "m": "basicmodel", "neutral": "basicmodel"},
        }[version][letter]
        vtag = "v1.0.0" if version == "1.0" else "v1.1.0"
        name = f"{stem}_{letter}_lbs_10_207_0_{vtag}.{fmt}"
    else:
        name = f"SMPL_{g.upper()}.{fmt}"
    path = dirpath / name
    if fmt == "pkl":
        out = {
            "J_regressor_prior": sp.csc_matrix(d["J_regressor_prior"]),
            "f": d["f"],
            "J_regressor": sp.csc_matrix(d["J_regressor"]),
            "kintree_table": d["kintree_table"],
            "J": d["J"],
            "weights_prior": d["weights_prior"],
            "weights": d["weights"],
            "vert_sym_idxs": d["vert_sym_idxs"],
            "posedirs": d["posedirs"],
            "pose_training_info": {"rot_type": "lrotmin", "n_subjects": 40, "n_poses": 1786, "lambda": 0.01},
            "bs_style": "lbs",
            "v_template": d["v_template"],
            "shapedirs": _ch(d["shapedirs"]),
            "bs_type": "lrotmin",
        }
        return dump_legacy_pickle(out, path)
    if fmt == "npz":
        keys = [
            "J_regressor_prior",
            "f",
            "J_regressor",
            "kintree_table",
            "J",
            "weights_prior",
            "weights",
            "vert_sym_idxs",
            "posedirs",
            "bs_style",
            "v_template",
            "shapedirs",
            "bs_type",
        ]
        return _npz(
            path,
            {k: (np.asarray(d[k]) if k not in ("bs_style", "bs_type") else np.array(d[k])) for k in keys},
        )
    raise ValueError("fmt must be 'pkl' or 'npz'")


def _smplh_arrays(gender: str, seed: int, n_shape: int):
    g = _norm_gender(gender)
    skel = _smplh_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("smplh", g, seed, SMPL_VERTS, SMPL_FACES, skel, 16, 0.02, 2e-3)
    d["shapedirs"] = np.ascontiguousarray(d["shapedirs"][:, :, :n_shape])
    w_prior = d["weights"] * rng.uniform(0.8, 1.2, d["weights"].shape)
    d["weights_prior"] = w_prior / w_prior.sum(axis=1, keepdims=True)
    d["J_regressor_prior"] = _regressor(rng, mesh.v, skel.pos)
    comps_r, mean_r, coeffs_r = _hand_pca(seed)
    comps_l, mean_l, coeffs_l = _left_from_right_pca(comps_r, mean_r, coeffs_r)
    d.update(
        hands_componentsl=comps_l,
        hands_componentsr=comps_r,
        hands_meanl=mean_l,
        hands_meanr=mean_r,
        hands_coeffsl=coeffs_l,
        hands_coeffsr=coeffs_r,
    )
    return d


_HAND_KEYS = (
    "hands_componentsl",
    "hands_componentsr",
    "hands_coeffsl",
    "hands_coeffsr",
    "hands_meanl",
    "hands_meanr",
)


def write_smplh(
    dirpath,
    gender: str = "neutral",
    fmt: str = "pkl",
    seed: int = 0,
    amass: bool | None = None,
    hand_pca: bool | None = None,
    official_name: bool = False,
) -> Path:
    """Fake SMPL+H model (6890 vertices, 52 joints = 22 body + 2 x 15 fingers, 459 features).

    Three real-world flavours:

    * ``fmt="pkl"`` (default ``hand_pca=True``): the file smplx expects after its
      ``tools/merge_smplh_mano.py``: the MANO download's SMPL+H pickle with MANO's hand PCA
      added as ``hands_components{l,r}`` (45, 45), ``hands_mean{l,r}`` (45,),
      ``hands_coeffs{l,r}`` (1554, 45); chumpy converted to ndarray, ``J_regressor`` still
      ``csc_matrix``; 10 shape components; written by Python 3 (protocol 4, legacy module names).
    * ``fmt="pkl", hand_pca=False``: the raw MANO-download file (``mano_v1_2/models``): Python 2
      pickle, ``shapedirs`` a chumpy ``Ch``, no ``hands_*`` keys -- smplx cannot load it.
      ``official_name`` gives its real name ``SMPLH_{female|male}.pkl`` (lower case).
    * ``fmt="npz"`` / ``amass=True``: the "Extended SMPL+H model" used by AMASS: 16 shape
      components, dense regressors, **no** ``hands_*`` keys by default (so smplx fails with
      ``'Struct' object has no attribute 'hands_componentsl'``, as with the real file); with
      ``hand_pca=True`` the hand PCA is merged in (loadable by smplx with ``ext="npz"``).
      ``official_name`` writes the AMASS layout ``{gender}/model.npz`` below ``dirpath``.

    Without ``official_name`` the name is ``SMPLH_{GENDER}.{ext}``. The hand PCA equals the one
    written by :func:`write_mano` for the same seed (left = mirrored right).
    """
    if amass is None:
        amass = fmt == "npz"
    if amass and fmt != "npz":
        raise ValueError("the AMASS SMPL+H model is an .npz")
    if hand_pca is None:
        hand_pca = not amass
    g = _norm_gender(gender)
    d = _smplh_arrays(g, seed, 16 if amass else 10)
    dirpath = Path(dirpath)
    if official_name:
        if amass:
            path = dirpath / g / "model.npz"
        else:
            path = dirpath / f"SMPLH_{g}.pkl"
    else:
        path = dirpath / f"SMPLH_{g.upper()}.{fmt}"
    path.parent.mkdir(parents=True, exist_ok=True)
    base = {
        "J_regressor_prior": d["J_regressor_prior"],
        "f": d["f"],
        "J_regressor": d["J_regressor"],
        "kintree_table": d["kintree_table"],
        "J": d["J"],
        "weights_prior": d["weights_prior"],
        "weights": d["weights"],
        "posedirs": d["posedirs"],
        "bs_style": "lbs",
        "v_template": d["v_template"],
        "shapedirs": d["shapedirs"],
        "bs_type": "lrotmin",
    }
    if hand_pca:
        base.update({k: d[k] for k in _HAND_KEYS})
    if fmt == "npz":
        return _npz(path, {k: np.asarray(v) for k, v in base.items()})
    if fmt != "pkl":
        raise ValueError("fmt must be 'pkl' or 'npz'")
    base["J_regressor_prior"] = sp.csc_matrix(base["J_regressor_prior"])
    base["J_regressor"] = sp.csc_matrix(base["J_regressor"])
    if hand_pca:  # merged by a Python 3 script: plain ndarrays, default protocol
        return dump_legacy_pickle(base, path, protocol=4, py2_strings=False)
    base["shapedirs"] = _ch(base["shapedirs"])
    return dump_legacy_pickle(base, path)


_SMPLX_JOINT_NAMES = [
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "jaw",
    "left_eye_smplhf",
    "right_eye_smplhf",
] + [f"{side}_{finger}{k}" for side in ("left", "right") for finger in _FINGER_ORDER for k in (1, 2, 3)]


def _smplx_arrays(gender: str, seed: int, layout: str):
    g = _norm_gender(gender)
    skel = _smplx_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("smplx", g, seed, SMPLX_VERTS, SMPLX_FACES, skel, 300, 0.02, 2e-3)
    expr = _expression(rng, mesh, skel, 100, 4e-3)
    if layout == "1.1":
        d["shapedirs"] = np.concatenate([d["shapedirs"], expr], axis=2)
    elif layout == "1.0":
        d["shapedirs"] = np.concatenate([d["shapedirs"][:, :, :10], expr[:, :, :10]], axis=2)
    else:
        raise ValueError("layout must be '1.0' or '1.1'")
    del d["J"]
    comps_r, mean_r, coeffs_r = _hand_pca(seed)
    comps_l, mean_l, coeffs_l = _left_from_right_pca(comps_r, mean_r, coeffs_r)
    d.update(
        hands_componentsl=comps_l,
        hands_componentsr=comps_r,
        hands_meanl=mean_l,
        hands_meanr=mean_r,
        hands_coeffsl=coeffs_l,
        hands_coeffsr=coeffs_r,
    )
    front = _head_faces(mesh, skel, d["f"], front=True)
    allhead = _head_faces(mesh, skel, d["f"], front=False)
    d["lmk_faces_idx"] = rng.choice(front, 51, replace=False).astype(np.int64)
    d["lmk_bary_coords"] = _bary(rng, 51)
    d["dynamic_lmk_faces_idx"] = rng.choice(allhead, (79, 17)).astype(np.int64)
    d["dynamic_lmk_bary_coords"] = _bary(rng, (79, 17))
    d["vt"], d["ft"] = _seam_uvs(rng, mesh.v, d["f"], SMPLX_UVS)
    d["joint2num"] = {n: i for i, n in enumerate(_SMPLX_JOINT_NAMES)}
    parts = [
        "global",
        "head",
        "leftCalf",
        "leftFingers",
        "leftFoot",
        "leftForeArm",
        "leftHand",
        "leftShoulder",
        "leftThigh",
        "leftToes",
        "leftUpperArm",
        "neck",
        "rightCalf",
        "rightFingers",
        "rightFoot",
        "rightForeArm",
        "rightHand",
        "rightShoulder",
        "rightThigh",
        "rightToes",
        "rightUpperArm",
        "spine",
        "spine1",
        "spine2",
        "leftEye",
        "rightEye",
        "jaw",
    ]
    d["part2num"] = {n: i for i, n in enumerate(parts)}
    return mesh, d


def _seam_uvs(rng, v: np.ndarray, f: np.ndarray, n_uvs: int) -> tuple[np.ndarray, np.ndarray]:
    """A UV map with the structure of the official ones: ``vt`` (n_uvs, 2) float64 in [0, 1] -- one
    UV per vertex (cylindrical about the body axis) plus ``n_uvs - V`` seam duplicates of randomly
    chosen vertices -- and ``ft`` (F, 3) uint32, where about half the corners at a duplicated vertex
    use the duplicate (so a vertex has two UVs, as along a real seam)."""
    n_verts = v.shape[0]
    f = f.astype(np.int64)
    vt = np.empty((n_uvs, 2))
    vt[:n_verts, 0] = np.arctan2(v[:, 0], v[:, 2]) / (2 * np.pi) + 0.5
    vt[:n_verts, 1] = (v[:, 1] - v[:, 1].min()) / np.ptp(v[:, 1])
    dup = rng.choice(n_verts, n_uvs - n_verts, replace=False)
    vt[n_verts:] = np.clip(vt[dup] + rng.normal(0, 0.01, (len(dup), 2)), 0, 1)
    uv_of = np.full(n_verts, -1)
    uv_of[dup] = n_verts + np.arange(len(dup))
    ft = f.copy()
    swap = (uv_of[f] >= 0) & (rng.random(f.shape) < 0.5)
    ft[swap] = uv_of[f[swap]]
    return vt, ft.astype(np.uint32)


def write_smpl_uv_obj(dirpath, seed: int = 0, name: str = "smpl_uv.obj", shuffle_faces: bool = False) -> Path:
    """Fake of the UV map SMPL distributes as a separate Wavefront ``.obj``: the neutral SMPL
    template (6890 ``v`` lines), 7576 ``vt`` lines (seam duplicates, see :func:`_seam_uvs`) and the
    13776 SMPL faces as ``f v/vt v/vt v/vt`` (1-based), in the model's face order unless
    ``shuffle_faces`` (then the faces are permuted and their corners rotated, to test matching).

    The real file's vt count (7576) and face order are taken to be these; its other lines
    (``vn``, ``s``, comments) are not reproduced."""
    d = _smpl_arrays("neutral", seed, 10)
    rng = np.random.default_rng([seed, 7576])
    f = d["f"].astype(np.int64)
    vt, ft = _seam_uvs(rng, d["v_template"], f, SMPL_UVS)
    ft = ft.astype(np.int64)
    if shuffle_faces:
        order = rng.permutation(f.shape[0])
        shift = rng.integers(0, 3, f.shape[0])
        cols = (shift[:, None] + np.arange(3)[None]) % 3
        f = np.take_along_axis(f[order], cols, axis=1)
        ft = np.take_along_axis(ft[order], cols, axis=1)
    lines = ["# fake SMPL UV map (tests/fakes.py)"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in d["v_template"]]
    lines += [f"vt {u:.6f} {w:.6f}" for u, w in vt]
    lines += [f"f {a + 1}/{ta + 1} {b + 1}/{tb + 1} {c + 1}/{tc + 1}" for (a, b, c), (ta, tb, tc) in zip(f, ft)]
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    path = dirpath / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def write_smplx(
    dirpath,
    gender: str = "neutral",
    fmt: str = "npz",
    layout: str = "1.1",
    seed: int = 0,
    kid_template: bool = False,
) -> Path:
    """Fake SMPL-X model (10475 vertices, 20908 faces, 55 joints, 486 features).

    ``layout="1.1"``: ``shapedirs`` (10475, 3, 400) = 300 shape + 100 expression components;
    ``"1.0"``: (10475, 3, 20) = 10 + 10. Keys: ``v_template``, ``f``, ``shapedirs``,
    ``posedirs``, ``J_regressor`` (55, 10475) dense, ``weights``, ``kintree_table``, hand PCA
    (``hands_components{l,r}``, ``hands_mean{l,r}``, ``hands_coeffs{l,r}``), landmarks
    (``lmk_faces_idx`` (51,), ``lmk_bary_coords`` (51, 3), ``dynamic_lmk_faces_idx`` (79, 17),
    ``dynamic_lmk_bary_coords`` (79, 17, 3)), ``vt`` (11313, 2), ``ft`` (20908, 3),
    ``joint2num``/``part2num`` (dicts; 0-d object arrays in the ``.npz``), and in the ``.npz``
    the stray ``allow_pickle`` entry the official archives carry. No ``J``, no chumpy.
    Name ``SMPLX_{GENDER}.{npz|pkl}``. Expression blend shapes move only the face.
    ``kid_template=True`` also writes ``smplx_kid_template.npy`` beside it.
    """
    g = _norm_gender(gender)
    _, d = _smplx_arrays(g, seed, layout)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    path = dirpath / f"SMPLX_{g.upper()}.{fmt}"
    keys = [
        "hands_meanr",
        "hands_meanl",
        "lmk_bary_coords",
        "vt",
        "posedirs",
        "part2num",
        "hands_coeffsr",
        "lmk_faces_idx",
        "J_regressor",
        "dynamic_lmk_faces_idx",
        "hands_componentsr",
        "shapedirs",
        "dynamic_lmk_bary_coords",
        "ft",
        "hands_componentsl",
        "joint2num",
        "v_template",
        "f",
        "hands_coeffsl",
        "kintree_table",
        "weights",
    ]
    if kid_template:
        write_kid_template(dirpath, "smplx", seed=seed, gender=g)
    if fmt == "npz":
        out = {}
        for k in keys:
            out[k] = _object0(d[k]) if isinstance(d[k], dict) else d[k]
            if k == "posedirs":
                out["allow_pickle"] = np.array(True)
        return _npz(path, out)
    if fmt == "pkl":
        return dump_legacy_pickle({k: d[k] for k in keys}, path)
    raise ValueError("fmt must be 'npz' or 'pkl'")


def write_kid_template(dirpath, model_type: str = "smplx", seed: int = 0, gender: str = "neutral") -> Path:
    """``{smpl|smplx}_kid_template.npy``: a (V, 3) float64 child-proportioned template.

    smplx uses it with ``age="kid"`` and ``kid_template_path=...``: it centres the template and
    appends ``kid - v_template`` as one extra shape direction. Works for SMPL, SMPL+H (use the
    ``smpl`` one) and SMPL-X.
    """
    g = _norm_gender(gender)
    if model_type == "smplx":
        v = _smplx_arrays(g, seed, "1.0")[1]["v_template"]
    elif model_type in ("smpl", "smplh"):
        v = _smpl_arrays(g, seed, 10)["v_template"]
        model_type = "smpl"
    else:
        raise ValueError("model_type must be 'smpl' or 'smplx'")
    rng = np.random.default_rng([seed, 4242])
    c = v.mean(axis=0)
    kid = (v - c) * np.array([0.62, 0.6, 0.62]) + c + rng.normal(0, 0.002, v.shape)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    path = dirpath / f"{model_type}_kid_template.npy"
    np.save(path, kid)
    return path


def write_smplx_kid_template(dirpath, seed: int = 0) -> Path:
    """``smplx_kid_template.npy`` (10475, 3); see :func:`write_kid_template`."""
    return write_kid_template(dirpath, "smplx", seed=seed)


def _mano_right(seed: int):
    skel = _mano_skel()
    _, mesh, d = _core("mano", "neutral", seed, MANO_VERTS, MANO_FACES, skel, 10, 0.005, 1e-3)
    d["shapedirs"] = d["shapedirs"].copy()
    d["shapedirs"][:, :, 0] = (mesh.v - mesh.v.mean(axis=0)) * 0.04  # overall hand size
    comps, mean, coeffs = _hand_pca(seed)
    d.update(hands_components=comps, hands_mean=mean, hands_coeffs=coeffs)
    return d


# R'[a, b] = s_a s_b R[a, b] for the mirror M = diag(-1, 1, 1)
_S = np.array([-1.0, 1.0, 1.0])
_POSE_FEATURE_MIRROR = np.outer(_S, _S).ravel()


def _mano_left(seed: int):
    r = _mano_right(seed)
    d = dict(r)
    d["v_template"] = r["v_template"] * _S
    d["J"] = r["J"] * _S
    d["f"] = r["f"][:, [0, 2, 1]].copy()
    n_feat = r["posedirs"].shape[2]
    feat = np.tile(_POSE_FEATURE_MIRROR, n_feat // 9)
    d["posedirs"] = r["posedirs"] * _S[None, :, None] * feat[None, None, :]
    # The official MANO_LEFT.pkl has shapedirs[:, 0, :] with the *same* sign as the right hand
    # (a true mirror would negate it); reproduce that known defect: y, z mirrored (unchanged),
    # x NOT negated.
    d["shapedirs"] = r["shapedirs"].copy()
    comps, mean, coeffs = _left_from_right_pca(r["hands_components"], r["hands_mean"], r["hands_coeffs"])
    d.update(hands_components=comps, hands_mean=mean, hands_coeffs=coeffs)
    return d


def write_mano(dirpath, side: str = "right", seed: int = 0) -> Path:
    """Fake ``MANO_RIGHT.pkl`` / ``MANO_LEFT.pkl`` (778 vertices, 16 joints, 135 features).

    Python 2 pickle with ``hands_components`` (45, 45) (rows = PCA directions scaled by their
    standard deviation, as in the real file), ``hands_mean`` (45,), ``hands_coeffs``
    (1554, 45), ``f`` (1538, 3), ``J_regressor`` csc (16, 778), ``kintree_table``, ``J``,
    ``bs_style``, ``bs_type``, ``weights``, ``posedirs`` (778, 3, 135), ``v_template``,
    ``shapedirs`` (778, 3, 10) chumpy ``Ch``. Joint order: wrist, index1-3, middle1-3,
    pinky1-3, ring1-3, thumb1-3.

    The left hand is the exact mirror (x -> -x) of the right one -- vertices, joints, reversed
    face winding, mirrored pose correctives and hand PCA (axis-angle (x, y, z) -> (x, -y, -z))
    -- except ``shapedirs[:, 0, :]``, which keeps the right hand's sign, reproducing the known
    defect of the official ``MANO_LEFT.pkl``.
    """
    side = side.lower()
    if side not in ("right", "left"):
        raise ValueError("side must be 'right' or 'left'")
    d = _mano_right(seed) if side == "right" else _mano_left(seed)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    out = {
        "hands_components": d["hands_components"],
        "f": d["f"],
        "J_regressor": sp.csc_matrix(d["J_regressor"]),
        "kintree_table": d["kintree_table"],
        "J": d["J"],
        "bs_style": "lbs",
        "hands_coeffs": d["hands_coeffs"],
        "weights": d["weights"],
        "posedirs": d["posedirs"],
        "hands_mean": d["hands_mean"],
        "v_template": d["v_template"],
        "shapedirs": _ch(d["shapedirs"]),
        "bs_type": "lrotmin",
    }
    return dump_legacy_pickle(out, dirpath / f"MANO_{side.upper()}.pkl")


def _flame_arrays(gender: str, seed: int):
    g = _norm_gender(gender)
    skel = _flame_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("flame", g, seed, FLAME_VERTS, FLAME_FACES, skel, 300, 0.004, 1e-3)
    expr = _expression(rng, mesh, skel, 100, 3e-3)
    d["shapedirs"] = np.concatenate([d["shapedirs"], expr], axis=2)
    front = _head_faces(mesh, skel, d["f"], front=True)
    allhead = _head_faces(mesh, skel, d["f"], front=False)
    lrng = np.random.default_rng([seed, 5151])
    lmk = {
        "static": (lrng.choice(front, 51, replace=False).astype(np.uint32), _bary(lrng, 51)),
        "dynamic": (lrng.choice(allhead, (79, 17)).astype(np.uint32), _bary(lrng, (79, 17))),
    }
    return d, lmk


def write_flame_landmarks(dirpath, seed: int = 0) -> tuple[Path, Path]:
    """``flame_static_embedding.pkl`` and ``flame_dynamic_embedding.npy`` (what smplx reads).

    Static: Python 2 pickle of ``{"lmk_face_idx": (51,) uint32, "lmk_b_coords": (51, 3)}``.
    Dynamic: a ``.npy`` holding a 0-d object array with the dict ``{"lmk_face_idx": (79, 17)
    uint32, "lmk_b_coords": (79, 17, 3)}`` (needs ``allow_pickle=True, encoding="latin1"``).
    Face indices refer to the FLAME mesh of the same seed (any gender: same topology).
    """
    _, lmk = _flame_arrays("neutral", seed)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    static = dump_legacy_pickle(
        {"lmk_face_idx": lmk["static"][0], "lmk_b_coords": lmk["static"][1]},
        dirpath / "flame_static_embedding.pkl",
    )
    dynamic = _save_legacy_npy_object(
        {"lmk_face_idx": lmk["dynamic"][0], "lmk_b_coords": lmk["dynamic"][1]},
        dirpath / "flame_dynamic_embedding.npy",
    )
    return static, dynamic


def write_flame(
    dirpath, gender: str = "neutral", seed: int = 0, official_name: bool = False, landmarks: bool = True
) -> Path:
    """Fake FLAME 2020 model (5023 vertices, 9976 faces, 5 joints, 36 features).

    Joints: global (root), neck, jaw, left eye, right eye (parents -1, 0, 1, 1, 1), matching
    smplx's pose order [global, neck, jaw, leye, reye]. Python 2 pickle with ``f``,
    ``v_template``, ``shapedirs`` (5023, 3, 400) chumpy ``Ch`` (300 shape + 100 expression,
    expressions move only the face), ``posedirs`` (5023, 3, 36), ``J_regressor`` csc (5, 5023),
    ``kintree_table``, ``J``, ``weights``, ``bs_style``, ``bs_type``.

    smplx 0.1.28 reads ``<dir>/FLAME_{GENDER}.pkl`` (gender upper-cased, default NEUTRAL);
    the download names them ``generic_model.pkl`` / ``male_model.pkl`` / ``female_model.pkl``
    (``official_name=True``; gender ``"generic"`` == ``"neutral"``). With ``landmarks`` the two
    embedding files smplx also needs are written beside it (:func:`write_flame_landmarks`).
    """
    g = _norm_gender(gender)
    d, _ = _flame_arrays(g, seed)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    if official_name:
        name = {"neutral": "generic", "male": "male", "female": "female"}[g] + "_model.pkl"
    else:
        name = f"FLAME_{g.upper()}.pkl"
    out = {
        "f": d["f"],
        "v_template": d["v_template"],
        "shapedirs": _ch(d["shapedirs"]),
        "posedirs": d["posedirs"],
        "J_regressor": sp.csc_matrix(d["J_regressor"]),
        "kintree_table": d["kintree_table"],
        "J": d["J"],
        "weights": d["weights"],
        "bs_style": "lbs",
        "bs_type": "lrotmin",
    }
    path = dump_legacy_pickle(out, dirpath / name)
    if landmarks:
        write_flame_landmarks(dirpath, seed)
    return path


def _link(src: Path, dst: Path) -> Path:
    """Same bytes under another name (hard link when possible)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    if dst.exists():
        dst.unlink()
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)
    return dst


def write_all(dirpath, seed: int = 0) -> dict:
    """Write a model tree usable as ``smplx.create(dirpath, model_type=...)``; return its paths.

    Layout (``*`` = loadable by smplx 0.1.28)::

        smpl/SMPL_NEUTRAL.pkl    * v1.1, 300 betas          key "smpl_neutral_pkl"
        smpl/SMPL_NEUTRAL.npz      same numbers, npz          "smpl_neutral_npz"
        smpl/SMPL_MALE.pkl       * v1.0, 10 betas           "smpl_male_pkl"
        smpl/SMPL_FEMALE.pkl     * v1.0, 10 betas           "smpl_female_pkl"
        smpl/smpl_kid_template.npy                           "smpl_kid_template"
        smplh/SMPLH_NEUTRAL.pkl  * merged, 10 betas          "smplh_neutral_pkl"
        smplh/SMPLH_FEMALE.npz   * AMASS + merged hand PCA, 16 betas   "smplh_female_npz"
        smplx/SMPLX_NEUTRAL.npz  * layout 1.1 (300 + 100)    "smplx_neutral_npz"
        smplx/SMPLX_NEUTRAL.pkl  * same numbers, pkl         "smplx_neutral_pkl"
        smplx/SMPLX_MALE.npz     * layout 1.0 (10 + 10)      "smplx_male_npz"
        smplx/smplx_kid_template.npy                         "smplx_kid_template"
        mano/MANO_RIGHT.pkl      *                           "mano_right_pkl"
        mano/MANO_LEFT.pkl       *                           "mano_left_pkl"
        flame/FLAME_NEUTRAL.pkl  *                           "flame_neutral_pkl"
        flame/flame_static_embedding.pkl                     "flame_static_embedding"
        flame/flame_dynamic_embedding.npy                    "flame_dynamic_embedding"
        official/smpl/basicModel_f_lbs_10_207_0_v1.0.0.pkl   (= SMPL_FEMALE.pkl)
                                                             "official_smpl_f_v1_0_pkl"
        official/smpl/basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl  (= SMPL_NEUTRAL.pkl)
                                                             "official_smpl_neutral_v1_1_pkl"
        official/smplh/SMPLH_male.pkl    raw MANO download: Ch, no hand PCA
                                                             "official_smplh_male_pkl"
        official/smplh_amass/neutral/model.npz  raw AMASS: 16 betas, no hand PCA
                                                             "official_smplh_amass_neutral_npz"
        official/flame/generic_model.pkl  (= FLAME_NEUTRAL.pkl)  "official_flame_generic_pkl"

    plus ``"root"``. Files with the same numbers are hard links (or copies).
    """
    global _CACHE
    _CACHE = {}
    try:
        return _write_all(Path(dirpath), seed)
    finally:
        _CACHE = None


def _write_all(root: Path, seed: int) -> dict:
    p = {"root": root}
    smpl, smplh, smplx_d = root / "smpl", root / "smplh", root / "smplx"
    mano, flame, off = root / "mano", root / "flame", root / "official"
    p["smpl_neutral_pkl"] = write_smpl(smpl, "neutral", "1.1", "pkl", seed)
    p["smpl_neutral_npz"] = write_smpl(smpl, "neutral", "1.1", "npz", seed)
    p["smpl_male_pkl"] = write_smpl(smpl, "male", "1.0", "pkl", seed)
    p["smpl_female_pkl"] = write_smpl(smpl, "female", "1.0", "pkl", seed)
    p["smpl_kid_template"] = write_kid_template(smpl, "smpl", seed)
    p["official_smpl_f_v1_0_pkl"] = _link(p["smpl_female_pkl"], off / "smpl" / "basicModel_f_lbs_10_207_0_v1.0.0.pkl")
    p["official_smpl_neutral_v1_1_pkl"] = _link(
        p["smpl_neutral_pkl"], off / "smpl" / "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl"
    )
    _CACHE.clear()
    p["smplh_neutral_pkl"] = write_smplh(smplh, "neutral", "pkl", seed)
    p["smplh_female_npz"] = write_smplh(smplh, "female", "npz", seed, amass=True, hand_pca=True)
    p["official_smplh_male_pkl"] = write_smplh(off / "smplh", "male", "pkl", seed, hand_pca=False, official_name=True)
    p["official_smplh_amass_neutral_npz"] = write_smplh(
        off / "smplh_amass", "neutral", "npz", seed, amass=True, official_name=True
    )
    _CACHE.clear()
    p["smplx_neutral_npz"] = write_smplx(smplx_d, "neutral", "npz", "1.1", seed)
    p["smplx_neutral_pkl"] = write_smplx(smplx_d, "neutral", "pkl", "1.1", seed)
    p["smplx_male_npz"] = write_smplx(smplx_d, "male", "npz", "1.0", seed)
    p["smplx_kid_template"] = write_kid_template(smplx_d, "smplx", seed)
    _CACHE.clear()
    p["mano_right_pkl"] = write_mano(mano, "right", seed)
    p["mano_left_pkl"] = write_mano(mano, "left", seed)
    p["flame_neutral_pkl"] = write_flame(flame, "neutral", seed)
    p["flame_static_embedding"] = flame / "flame_static_embedding.pkl"
    p["flame_dynamic_embedding"] = flame / "flame_dynamic_embedding.npy"
    p["official_flame_generic_pkl"] = _link(p["flame_neutral_pkl"], off / "flame" / "generic_model.pkl")
    return p
