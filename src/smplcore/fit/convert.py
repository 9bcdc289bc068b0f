"""Convert parameters between models (SMPL ↔ SMPL+H ↔ SMPL-X ↔ the open model) by fitting.

The source model's posed vertices are mapped to the target's vertices through a correspondence, and the
target is fitted to them with :func:`smplcore.fit.fit_vertices` (closed form, then exact). The
correspondence is, in order of preference:

1. an official deformation-transfer file (``smpl2smplx_deftrafo_setup.pkl`` and friends: a sparse
   ``mtx`` of shape (V_target, 2 V_source) whose first half maps vertices), read through smplcore's
   allow-list unpickler;
2. the identity, when both models share a mesh (same vertex count and faces);
3. computed from the two rest-pose templates: the target's template is aligned to the source's by the
   similarity (scale, rotation, translation) that best maps its skeleton joints onto the source's of the
   same names, then each target vertex takes the barycentric coordinates of its nearest point on the
   source surface. Computed maps are cached on disk (``cache_dir``, default
   ``~/.cache/smplcore/correspondences``), keyed by a hash of both meshes.

With ``method="joints"`` the target is fitted to the source's joints of the same names instead.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.fit import checks
from smplcore.fit.body import FitBody
from smplcore.fit.result import FitResult, as_array


@dataclass(frozen=True)
class Correspondence:
    """Target vertex i = Σ_c weights[i, c] · source vertex faces[i, c]; ``distance`` (V_t,) in the aligned
    rest pose (metres; 0 for an identity or a file), ``kind`` says where it came from."""

    indices: np.ndarray  # (V_t, k) source vertex ids (k = 3 for barycentric maps)
    weights: np.ndarray  # (V_t, k)
    distance: np.ndarray  # (V_t,)
    kind: str

    def apply(self, vertices: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """(B, V_t, 3) target-vertex positions from (B, V_s, 3) source vertices (only the target vertices
        ``rows`` when given), in the source vertices' precision."""
        indices, weights = (self.indices, self.weights) if rows is None else (self.indices[rows], self.weights[rows])
        weights = weights.astype(vertices.dtype)
        out = weights[:, 0, None] * vertices[:, indices[:, 0]]
        for c in range(1, indices.shape[1]):
            out += weights[:, c, None] * vertices[:, indices[:, c]]
        return out


def _source_vertices(model: Any, params: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The source's (B, V, 3) vertices and (B, J', 3) joints as NumPy arrays of its precision."""
    out = model(**params)
    verts, joints = out.vertices, out.joints
    if hasattr(verts, "detach"):
        verts, joints = verts.detach().cpu().numpy(), joints.detach().cpu().numpy()
    return np.asarray(verts), np.asarray(joints)


#: Source vertices one target vertex may be mapped from (official files: the 3 corners of a triangle). Bounds
#: the memory of a deformation-transfer file's map to 16 x 64 bytes per target vertex (~11 MB for SMPL-X).
MAX_SOURCES_PER_VERTEX = 64


def read_deformation_transfer(path: str | Path, num_source: int, num_target: int) -> Correspondence:
    """The vertex map of an official deformation-transfer pickle (``mtx`` or ``matrix``), read safely; rows
    with more than :data:`MAX_SOURCES_PER_VERTEX` weights are refused (memory bounded by the target's size)."""
    from smplcore.io import numeric_array, read_arrays

    path = Path(path)
    data = read_arrays(path, "a deformation-transfer file (.pkl)", sparse_stays_sparse=True)
    if not isinstance(data, Mapping) or not ({"mtx", "matrix"} & set(data)):
        raise ModelFileError(path, "expected a dict with a sparse 'mtx' (or 'matrix')", key="mtx")
    key = "mtx" if "mtx" in data else "matrix"
    mtx = data[key]
    mtx = mtx.tocsr() if hasattr(mtx, "tocsr") else numeric_array(path, mtx, key, kinds="biuf")
    if mtx.ndim != 2:
        raise ModelFileError(path, f"expected a 2-D matrix, found shape {mtx.shape}", key=key)
    rows, cols = mtx.shape
    if rows != num_target or cols not in (num_source, 2 * num_source):
        raise ModelFileError(
            path, f"maps ({rows}, {cols}); expected ({num_target}, {2 * num_source}) for these models", key=key
        )
    import scipy.sparse as sp

    mtx = sp.csr_matrix(mtx)[:, :num_source].tocsr()
    counts = np.diff(mtx.indptr)
    width = max(1, int(counts.max(initial=0)))
    if width > MAX_SOURCES_PER_VERTEX:  # the (V, width) tables below would take V x width x 16 bytes
        row = int(np.argmax(counts))
        raise ModelFileError(
            path,
            f"row {row} maps one target vertex from {width} source vertices; a deformation transfer uses a few "
            f"(a triangle's three; at most {MAX_SOURCES_PER_VERTEX} are accepted)",
            key=key,
        )
    if not np.all(np.isfinite(mtx.data)):
        raise ModelFileError(path, "holds NaN or infinite weights", key=key)
    indices = np.zeros((rows, width), np.int64)
    weights = np.zeros((rows, width))
    for i in range(rows):
        s, e = mtx.indptr[i], mtx.indptr[i + 1]
        indices[i, : e - s], weights[i, : e - s] = mtx.indices[s:e], mtx.data[s:e]
    return Correspondence(indices, weights, np.zeros(rows), "file")


def _similarity(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Scale s, rotation R, translation t minimising Σ |s R src + t − dst|² (Umeyama)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    u, sing, vt = np.linalg.svd(b.T @ a)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    corr = np.diag([1.0, 1.0, d])
    rot = u @ corr @ vt
    scale = float(np.trace(np.diag(sing) @ corr) / max(np.sum(a * a), 1e-300))
    return scale, rot, md - scale * rot @ ms


def closest_on_triangles(points: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of triangles to points: barycentric coordinates (n, k, 3) and squared distances (n, k)
    for (n, 3) points and (n, k, 3, 3) candidate triangles (the region-based method of Ericson)."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    p = points[:, None, :]
    ab, ac, ap = b - a, c - a, p - a
    d00, d01, d11 = np.sum(ab * ab, -1), np.sum(ab * ac, -1), np.sum(ac * ac, -1)
    d20, d21 = np.sum(ap * ab, -1), np.sum(ap * ac, -1)
    denom = np.maximum(d00 * d11 - d01 * d01, 1e-300)
    v = (d11 * d20 - d01 * d21) / denom
    w = (d00 * d21 - d01 * d20) / denom
    inside = (v >= 0) & (w >= 0) & (v + w <= 1)
    best_bary = np.stack([1 - v - w, v, w], -1)
    best = np.where(inside, np.sum((p - (a + v[..., None] * ab + w[..., None] * ac)) ** 2, -1), np.inf)
    # outside: the closest point lies on an edge
    for (i, j), (e0, e1) in {(0, 1): (a, b), (0, 2): (a, c), (1, 2): (b, c)}.items():
        edge = e1 - e0
        t = np.clip(np.sum((p - e0) * edge, -1) / np.maximum(np.sum(edge * edge, -1), 1e-300), 0, 1)
        d = np.sum((p - (e0 + t[..., None] * edge)) ** 2, -1)
        better = ~inside & (d < best)
        bary = np.zeros_like(best_bary)
        bary[..., i], bary[..., j] = 1 - t, t
        best_bary = np.where(better[..., None], bary, best_bary)
        best = np.where(better, d, best)
    return best_bary, best


def template_correspondence(source: FitBody, target: FitBody, candidates: int = 16) -> Correspondence:
    """Nearest-surface barycentric map from the target's rest template to the source's (after aligning)."""
    from scipy.spatial import cKDTree

    common = [n for n in target.output_joint_names[: target.num_joints] if n in source.output_joint_names]
    src_v, dst_v = source.template[: source.num_vertices], target.template[: target.num_vertices]
    if len(common) >= 3:
        s_idx = [source.output_joint_names.index(n) for n in common]
        t_idx = [target.output_joint_names.index(n) for n in common]
        scale, rot, shift = _similarity(target.joint_template[t_idx], source.joint_template[s_idx])
        dst_v = scale * dst_v @ rot.T + shift
    faces = source.faces
    tri = src_v[faces]
    tree = cKDTree(tri.mean(1))
    k = min(candidates, len(faces))
    _, cand = tree.query(dst_v, k=k)
    cand = cand.reshape(len(dst_v), k)
    bary, dist2 = closest_on_triangles(dst_v, tri[cand])
    pick = np.argmin(dist2, axis=1)
    rows = np.arange(len(dst_v))
    return Correspondence(
        faces[cand[rows, pick]].astype(np.int64), bary[rows, pick], np.sqrt(dist2[rows, pick]), "templates"
    )


def _mesh_key(body: FitBody) -> bytes:
    h = hashlib.sha256()
    for a in (body.template[: body.num_vertices], body.faces, body.joint_template):
        h.update(np.ascontiguousarray(a, np.float64 if a.dtype.kind == "f" else np.int64).tobytes())
    return h.digest()


def correspondence(
    source_model: Any, target_model: Any, *, deformation_transfer: str | Path | None = None, cache_dir: Any = None
) -> Correspondence:
    """The vertex map from ``source_model`` to ``target_model`` (see the module docstring)."""
    source, target = FitBody.from_model(source_model), FitBody.from_model(target_model)
    if deformation_transfer is not None:
        return read_deformation_transfer(deformation_transfer, source.num_vertices, target.num_vertices)
    same_mesh = source.num_vertices == target.num_vertices and np.array_equal(source.faces, target.faces)
    if same_mesh:
        n = source.num_vertices
        ids = np.repeat(np.arange(n)[:, None], 3, 1)
        return Correspondence(ids, np.tile([1.0, 0.0, 0.0], (n, 1)), np.zeros(n), "identity")
    folder = Path(cache_dir or os.environ.get("SMPLCORE_CACHE") or Path.home() / ".cache" / "smplcore")
    folder = folder / "correspondences"
    name = hashlib.sha256(_mesh_key(source) + _mesh_key(target)).hexdigest()[:24] + ".npz"
    path = folder / name
    if path.is_file():
        from smplcore.io import numeric_array, read_npz

        try:
            data = read_npz(path, "a cached correspondence (.npz)")
            indices, weights, distance = (numeric_array(path, data[k], k) for k in ("indices", "weights", "distance"))
            return Correspondence(indices, weights, distance, "templates (cached)")
        except (ModelFileError, KeyError):
            pass  # a damaged cache entry: computed again and replaced
    corr = template_correspondence(source, target)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, indices=corr.indices, weights=corr.weights, distance=corr.distance)
        os.replace(tmp, path)
    except OSError:  # a read-only home: the map is just not cached
        pass
    return corr


def convert(
    params: dict[str, Any],
    source_model: Any,
    target_model: Any,
    *,
    method: str = "vertices",
    deformation_transfer: str | Path | None = None,
    cache_dir: str | Path | None = None,
    points: int | None = 2000,
    **fit_options: Any,
) -> FitResult:
    """Parameters of ``target_model`` that reproduce ``source_model(**params)``.

    Parameters
    ----------
    params : forward keywords of the source model (batch B).
    source_model, target_model : torch models of :func:`smplcore.create` or :class:`smplcore.BodyModel`.
    method : ``"vertices"`` (through a vertex correspondence) or ``"joints"`` (the skeleton joints the
        two models share by name).
    deformation_transfer : an official deformation-transfer ``.pkl`` (source → target), optional.
    cache_dir : where computed correspondences are cached.
    points : how many of the target's vertices are fitted (spread over the mesh, every part represented;
        the parameters of a 10k-vertex mesh are settled by a few thousand of its vertices, ~0.05 mm from
        the fit to all of them), None for every vertex. The error is always measured on every vertex.
    fit_options : passed to :func:`smplcore.fit.fit_vertices` (``tol`` defaults to 1e-3 here: a converted
        body settles within a few µm of its optimum) / :func:`smplcore.fit.fit_joints`.

    Returns
    -------
    FitResult whose ``vertex_error`` (B,) is the mean distance (metres) between the target's fitted mesh and
    the mapped source vertices (``joint_error`` with ``method="joints"``).

    Examples
    --------
    >>> import numpy as np, smplcore
    >>> from smplcore import fit
    >>> model = smplcore.BodyModel(model_type="open")
    >>> params = {"body_pose": np.full((1, 69), 0.1)}
    >>> r = fit.convert(params, model, model)
    >>> bool(r.vertex_error[0] < 1e-3)
    True
    """
    from smplcore.fit.joints import fit_joints
    from smplcore.fit.vertices import fit_vertices

    if not isinstance(params, dict):
        raise TypeError(f"params: expected a dict of the source model's forward keywords, got {type(params).__name__}")
    if points is not None:
        points = checks.count("points", points, 3)
    for name, value in params.items():
        if value is not None:
            as_array(value, f"params[{name!r}]")
    verts, joints = _source_vertices(source_model, params)
    if method == "joints":
        source, target = FitBody.from_model(source_model), FitBody.from_model(target_model)
        names = [n for n in target.output_joint_names[: target.num_joints] if n in source.output_joint_names]
        if len(names) < 3:
            raise ValueError("method='joints': the two models share fewer than 3 joint names")
        picked = [source.output_joint_names.index(n) for n in names]
        # a conversion reproduces the source body, outside the anatomical limits too
        return fit_joints(target_model, joints[:, picked], joint_names=names, **{"joint_limits": 0.0, **fit_options})
    if method != "vertices":
        raise ValueError(f"method: expected 'vertices' or 'joints', got {method!r}")
    corr = correspondence(source_model, target_model, deformation_transfer=deformation_transfer, cache_dir=cache_dir)
    mapped = corr.apply(verts)
    target = FitBody.from_model(target_model)
    if points is None or points >= target.num_vertices:
        return fit_vertices(target_model, mapped, **{"tol": 1e-3, **fit_options})
    from smplcore.fit.vertices import spread_subset

    ids = spread_subset(target, np.arange(target.num_vertices), int(points), per_part=16)
    result = fit_vertices(target_model, mapped[:, ids], vertex_ids=ids, **{"tol": 1e-3, **fit_options})
    fitted = target_model(**result.params).vertices
    if hasattr(fitted, "detach"):
        fitted = fitted.detach().cpu().numpy()
    result.vertex_error = np.sqrt(np.einsum("bvc,bvc->bv", fitted - mapped, fitted - mapped)).mean(1)
    return result
