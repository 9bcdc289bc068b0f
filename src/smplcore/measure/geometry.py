"""Mesh geometry for measuring: plane sections split into loops, tape-measure girths, closed volumes.

Everything here works on plain ``(V, 3)`` vertices and ``(F, 3)`` triangles with NumPy and SciPy, and
returns, with each value, its gradient with respect to the vertices (the cut's edges and interpolation
weights held fixed), which :func:`smplcore.measure.fit_shape` chains through the shape basis.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError

__all__ = ["Topology", "Loop", "topology", "section", "hull_girth", "volume", "Linear"]


@dataclass(frozen=True)
class Topology:
    """Edges of a triangle mesh: ``edges`` (E, 2) vertex pairs, ``face_edges`` (F, 3) edge of each
    face side (side k joins corners k and k+1), ``boundary`` (B, 2) directed boundary edges (as in
    their face) and ``boundary_loop`` (B,) the hole each belongs to."""

    faces: np.ndarray
    edges: np.ndarray
    face_edges: np.ndarray
    boundary: np.ndarray
    boundary_loop: np.ndarray
    num_holes: int


def _build_topology(faces: np.ndarray) -> Topology:
    f = np.asarray(faces, dtype=np.int64)
    sides = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1).reshape(-1, 2)  # (3F, 2)
    key = np.sort(sides, axis=1)
    edges, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    face_edges = inverse.reshape(-1, 3)
    boundary = sides[counts[inverse] == 1]
    if len(boundary):
        nv = int(f.max()) + 1
        graph = coo_matrix((np.ones(len(boundary)), (boundary[:, 0], boundary[:, 1])), shape=(nv, nv))
        _, labels = connected_components(graph, directed=False)
        used, loop = np.unique(labels[boundary[:, 0]], return_inverse=True)
        num_holes = len(used)
    else:
        loop, num_holes = np.zeros(0, dtype=np.int64), 0
    return Topology(f, edges, face_edges, boundary, np.asarray(loop, dtype=np.int64), int(num_holes))


@lru_cache(maxsize=8)
def _cached_topology(data: bytes, shape: tuple[int, int]) -> Topology:
    return _build_topology(np.frombuffer(data, dtype=np.int64).reshape(shape))


def topology(faces: np.ndarray) -> Topology:
    """The edges and holes of a mesh's triangles (F, 3), cached per distinct face array."""
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces: expected an (F, 3) integer array, got shape {f.shape}")
    return _cached_topology(f.tobytes(), f.shape)


@dataclass
class Linear:
    """A measured value and its first-order dependence on the vertices: ``value`` ≈ value0 +
    Σ_k ``weights[k]`` · (v[``rows[k]``] − v0[``rows[k]``]) with ``weights`` (K, 3)."""

    value: float
    rows: np.ndarray
    weights: np.ndarray

    @staticmethod
    def constant(value: float) -> Linear:
        return Linear(float(value), np.zeros(0, dtype=np.int64), np.zeros((0, 3)))

    def __add__(self, other: Linear) -> Linear:
        return Linear(
            self.value + other.value,
            np.concatenate([self.rows, other.rows]),
            np.concatenate([self.weights, other.weights]),
        )

    def __sub__(self, other: Linear) -> Linear:
        return self + other.scaled(-1.0)

    def scaled(self, factor: float) -> Linear:
        return Linear(self.value * factor, self.rows, self.weights * factor)


@dataclass
class Loop:
    """One connected curve of a plane section: ``points`` (N, 3) on the edges ``edge`` (N,) at
    ``t`` (N,) from the edge's first vertex; ``closed`` when it does not end at a hole."""

    points: np.ndarray
    edge: np.ndarray
    t: np.ndarray
    closed: bool


def _basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = normal / np.linalg.norm(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def section(vertices: np.ndarray, topo: Topology, point: np.ndarray, normal: np.ndarray) -> list[Loop]:
    """The curves where the plane through ``point`` (3,) with ``normal`` (3,) cuts the mesh.

    Vertices exactly on the plane count as above it, so every cut face has exactly two cut edges;
    the cut edges are joined through their faces into connected loops.
    """
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    d = (vertices - np.asarray(point, dtype=np.float64)) @ n
    above = d >= 0.0
    e = topo.edges
    cut = above[e[:, 0]] != above[e[:, 1]]
    if not cut.any():
        return []
    fcut = cut[topo.face_edges]  # (F, 3)
    faces_cut = fcut.sum(axis=1) == 2
    pairs = topo.face_edges[faces_cut][fcut[faces_cut]].reshape(-1, 2)  # two cut edges per cut face
    ids = np.flatnonzero(cut)
    local = np.full(len(e), -1, dtype=np.int64)
    local[ids] = np.arange(len(ids))
    a, b = local[pairs[:, 0]], local[pairs[:, 1]]
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(len(ids), len(ids)))
    count, labels = connected_components(graph, directed=False)
    degree = np.bincount(np.concatenate([a, b]), minlength=len(ids))
    da, db = d[e[ids, 0]], d[e[ids, 1]]
    t = da / (da - db)
    pts = vertices[e[ids, 0]] + t[:, None] * (vertices[e[ids, 1]] - vertices[e[ids, 0]])
    loops = []
    for k in range(count):
        m = labels == k
        loops.append(Loop(pts[m], ids[m], t[m], bool(np.all(degree[m] == 2))))
    return loops


def _hull(points2d: np.ndarray) -> ConvexHull | None:
    if len(points2d) < 3:
        return None
    try:
        return ConvexHull(points2d)
    except QhullError:
        return None


def pick_loop(loops: list[Loop], point: np.ndarray, normal: np.ndarray) -> Loop | None:
    """The loop whose convex hull contains ``point`` (projected on the plane), else the nearest one."""
    if not loops:
        return None
    u, w = _basis(np.asarray(normal, dtype=np.float64))
    c = np.array([point @ u, point @ w])
    best, best_dist = None, np.inf
    for loop in loops:
        p2 = np.stack([loop.points @ u, loop.points @ w], axis=1)
        hull = _hull(p2)
        if hull is not None and np.all(hull.equations[:, :2] @ c + hull.equations[:, 2] <= 1e-12):
            return loop
        dist = float(np.min(np.linalg.norm(p2 - c, axis=1)))
        if dist < best_dist:
            best, best_dist = loop, dist
    return best


def hull_girth(loop: Loop, topo: Topology, normal: np.ndarray) -> Linear:
    """A tape measure around ``loop``: the perimeter of its convex hull in the cutting plane (metres),
    with its gradient with respect to the vertices of the cut edges."""
    u, w = _basis(np.asarray(normal, dtype=np.float64))
    p2 = np.stack([loop.points @ u, loop.points @ w], axis=1)
    hull = _hull(p2)
    if hull is None:
        return Linear.constant(0.0)
    order = hull.vertices  # counter-clockwise
    p = loop.points[order]
    nxt, prv = np.roll(p, -1, axis=0), np.roll(p, 1, axis=0)
    to_next, to_prev = p - nxt, p - prv
    ln, lp = np.linalg.norm(to_next, axis=1), np.linalg.norm(to_prev, axis=1)
    grad = to_next / np.maximum(ln, 1e-15)[:, None] + to_prev / np.maximum(lp, 1e-15)[:, None]  # (H, 3)
    edge = topo.edges[loop.edge[order]]
    t = loop.t[order][:, None]
    rows = np.concatenate([edge[:, 0], edge[:, 1]])
    weights = np.concatenate([grad * (1.0 - t), grad * t])
    return Linear(float(ln.sum()), rows, weights)


def volume(vertices: np.ndarray, topo: Topology) -> Linear:
    """Enclosed volume (m³) by the divergence theorem, holes closed first.

    Each hole (a loop of edges used by one face only: SMPL's open eyes or mouth, a cut neck) is closed
    by a fan of triangles from the hole's boundary edges to the mean of its boundary vertices, oriented
    like the faces around it, so the result is the volume of the mesh with flat-ish caps. The gradient
    covers the mesh's own faces (the caps' share is neglected). Faces wound inwards give the same volume.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = topo.faces
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    total = float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0
    if topo.num_holes:
        bd = topo.boundary
        centres = np.zeros((topo.num_holes, 3))
        np.add.at(centres, topo.boundary_loop, v[bd[:, 0]])
        centres /= np.bincount(topo.boundary_loop, minlength=topo.num_holes)[:, None]
        cap_c = centres[topo.boundary_loop]
        # boundary edge a->b as in its face; the cap triangle (b, a, centre) continues that orientation
        total += float(np.einsum("ij,ij->", v[bd[:, 1]], np.cross(v[bd[:, 0]], cap_c))) / 6.0
    rows = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    weights = np.concatenate([np.cross(b, c), np.cross(c, a), np.cross(a, b)]) / 6.0
    sign = -1.0 if total < 0 else 1.0  # faces wound inwards: the same volume
    return Linear(sign * total, rows, sign * weights)
