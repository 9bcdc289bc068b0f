"""Mesh generation around a skeleton: vertices, skinning weights, regressors, faces, blend shapes,
pose correctives, hand PCA, UV seams; one cached core per ``(model, gender, seed)``."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from .sizes import _GENDER_CODE, _MODEL_CODE, HAND_COEFF_ROWS, ROOT_PARENT
from .skeletons import _M, _Skel


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


@contextmanager
def core_cache():
    """Keep :func:`_core` results for the duration of the block (``write_all`` writes several
    files of the same numbers); yields a function that empties the cache."""
    global _CACHE
    _CACHE = {}
    try:
        yield _CACHE.clear
    finally:
        _CACHE = None


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
