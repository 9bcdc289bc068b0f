"""UV maps of body models: ``vt`` / ``ft`` inside model files, or a separate UV ``.obj``.

A UV map is a pair of arrays:

* ``vt`` (T, 2) texture coordinates in the OBJ convention (u right, v *up*, both in [0, 1] for a
  texture that is not tiled). ``T >= V`` in general: along seams one mesh vertex has several UVs.
* ``ft`` (F, 3) int64 indices into ``vt``, one row per mesh face, corner for corner with ``faces``.

SMPL-X ``.npz`` / ``.pkl`` files carry ``vt`` and ``ft``; SMPL's UV map is distributed as a separate
``.obj`` (read with :func:`load_uv_obj`, matched to a model with :func:`attach_uv`); smplcore's own
``.npz`` stores them under the same names, and the open model always has them.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.model_data import ModelData

__all__ = ["attach_uv", "check_uv", "load_uv_obj", "uv_from_file_arrays"]


def check_uv(path: str | Path, vt: Any, ft: Any, num_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Validated ``vt`` (T, 2) float64 and ``ft`` (F, 3) int64 for a mesh of ``num_faces`` faces.

    Raises
    ------
    ModelFileError
        naming ``path`` and the key (``vt`` or ``ft``) that is at fault.
    """
    vt = np.asarray(vt)
    ft = np.asarray(ft)
    if vt.dtype.kind not in "fiu" or vt.ndim != 2 or vt.shape[1] not in (2, 3) or vt.shape[0] < 1:
        raise ModelFileError(path, f"expected shape (T, 2) texture coordinates, found {vt.shape} {vt.dtype}", key="vt")
    vt = vt[:, :2].astype(np.float64)
    if not np.all(np.isfinite(vt)):
        raise ModelFileError(path, "contains NaN or infinite values", key="vt")
    if ft.dtype.kind not in "iu" or ft.ndim != 2 or ft.shape[1] != 3:
        raise ModelFileError(path, f"expected shape (F, 3) integer UV indices, found {ft.shape} {ft.dtype}", key="ft")
    if ft.shape[0] != num_faces:
        raise ModelFileError(path, f"expected one row per mesh face, (F={num_faces}, 3), found {ft.shape}", key="ft")
    if ft.size and (ft.min() < 0 or ft.max() >= vt.shape[0]):
        raise ModelFileError(
            path, f"indices must lie in [0, {vt.shape[0]}) (the rows of vt), found [{ft.min()}, {ft.max()}]", key="ft"
        )
    return vt, ft.astype(np.int64)


def uv_from_file_arrays(path: str | Path, raw: Mapping[str, Any], num_faces: int) -> dict[str, np.ndarray]:
    """``{"vt": ..., "ft": ...}`` from the raw arrays of a model file, or ``{}`` when it has no UVs.

    A file with only one of the two keys is rejected (a UV map needs both).
    """
    has_vt, has_ft = "vt" in raw, "ft" in raw
    if not (has_vt or has_ft):
        return {}
    if has_vt != has_ft:
        missing = "ft" if has_vt else "vt"
        raise ModelFileError(path, "a UV map needs both 'vt' and 'ft'; this file has only one", key=missing)
    vt, ft = raw["vt"], raw["ft"]
    vt = vt.toarray() if hasattr(vt, "toarray") else vt
    ft = ft.toarray() if hasattr(ft, "toarray") else ft
    vt, ft = check_uv(path, vt, ft, num_faces)
    return {"vt": vt, "ft": ft}


def load_uv_obj(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the UV map of a Wavefront ``.obj`` (such as the UV map SMPL distributes).

    Polygons are split into fans of triangles ``(0, i, i + 1)``, the way smplcore's meshes are.

    Returns
    -------
    vt : (T, 2) float64 texture coordinates (OBJ convention: v up).
    ft : (F, 3) int64 indices into ``vt`` per face corner.
    faces : (F, 3) int64 vertex indices of the same faces (to match them to a model's faces).

    Raises
    ------
    ModelFileError
        when the file is missing, a face has no texture index, or an index is out of range.
    """
    from smplcore.io import read_text

    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise ModelFileError(path, "no such UV file (expected a Wavefront .obj with 'vt' lines and 'f v/vt' faces)")
    text = read_text(path, "a UV map (a Wavefront .obj with 'vt' lines and 'f v/vt' faces)", 64 << 20)
    uvs: list[list[float]] = []
    tri_v: list[tuple[int, int, int]] = []
    tri_t: list[tuple[int, int, int]] = []
    num_v = 0
    for lineno, line in enumerate(text.splitlines(keepends=True), 1):
        if line.startswith("v "):
            num_v += 1
        elif line.startswith("vt "):
            parts = line.split()
            try:
                uvs.append([float(parts[1]), float(parts[2]) if len(parts) > 2 else 0.0])
            except (IndexError, ValueError):
                raise ModelFileError(path, f"line {lineno}: malformed 'vt' line {line.strip()!r}") from None
        elif line.startswith("f "):
            corners = line.split()[1:]
            vs, ts = [], []
            for corner in corners:
                fields = corner.split("/")
                if len(fields) < 2 or not fields[1]:
                    raise ModelFileError(
                        path, f"line {lineno}: face corner {corner!r} has no texture index (expected 'f v/vt ...')"
                    )
                try:
                    v, t = int(fields[0]), int(fields[1])
                except ValueError:
                    raise ModelFileError(path, f"line {lineno}: malformed face {line.strip()!r}") from None
                # OBJ indices are 1-based; negative ones count back from the last element read
                vs.append(v - 1 if v > 0 else num_v + v)
                ts.append(t - 1 if t > 0 else len(uvs) + t)
            if len(vs) < 3:
                raise ModelFileError(path, f"line {lineno}: a face needs at least 3 corners")
            for i in range(1, len(vs) - 1):
                tri_v.append((vs[0], vs[i], vs[i + 1]))
                tri_t.append((ts[0], ts[i], ts[i + 1]))
    if not uvs or not tri_t:
        raise ModelFileError(path, "holds no UV map (no 'vt' lines or no faces)")
    vt = np.asarray(uvs, dtype=np.float64)
    faces = np.asarray(tri_v, dtype=np.int64)
    if faces.min() < 0 or (num_v and faces.max() >= num_v):
        raise ModelFileError(path, f"face vertex indices out of range for its {num_v} vertices", key="f")
    vt, ft = check_uv(path, vt, np.asarray(tri_t, dtype=np.int64), faces.shape[0])
    return vt, ft, faces


def attach_uv(data: ModelData, uv_path: str | Path) -> ModelData:
    """``data`` with the UV map of ``uv_path`` (an ``.obj`` of the same mesh, see :func:`load_uv_obj`).

    The file's faces must be the model's faces: in the same order, or the same triangles in another
    order or with rotated corners (``ft`` is then permuted to the model's faces).

    Raises
    ------
    ModelFileError
        naming ``uv_path`` when its mesh is not the model's (different face count or triangles).
    """
    vt, ft, faces = load_uv_obj(uv_path)
    model_faces = np.asarray(data.faces, dtype=np.int64)
    what = f"{data.model_type} model from {data.source}"
    if faces.shape[0] != model_faces.shape[0]:
        raise ModelFileError(
            uv_path, f"has {faces.shape[0]} triangles, the {what} has {model_faces.shape[0]}: not the same mesh"
        )
    if not np.array_equal(faces, model_faces):
        ft = _align_faces(uv_path, faces, ft, model_faces, what)
    return data.replace(vt=vt, ft=ft)


def _align_faces(path: str | Path, faces: np.ndarray, ft: np.ndarray, model_faces: np.ndarray, what: str) -> np.ndarray:
    """``ft`` reordered so that row i belongs to ``model_faces[i]`` (faces matched up to corner rotation)."""

    # canonical rotation of each triangle: the smallest vertex index first (winding kept)
    def canonical(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        shift = np.argmin(tris, axis=1)
        cols = (shift[:, None] + np.arange(3)[None]) % 3
        return np.take_along_axis(tris, cols, axis=1), cols

    file_c, file_cols = canonical(faces)
    model_c, model_cols = canonical(model_faces)
    ft_c = np.take_along_axis(ft, file_cols, axis=1)
    top = int(max(file_c.max(), model_c.max())) + 1
    file_key = (file_c[:, 0] * top + file_c[:, 1]) * top + file_c[:, 2]
    model_key = (model_c[:, 0] * top + model_c[:, 1]) * top + model_c[:, 2]
    order = np.argsort(file_key, kind="stable")
    pos = np.searchsorted(file_key[order], model_key)
    pos = np.clip(pos, 0, len(order) - 1)
    found = file_key[order][pos] == model_key
    if not np.all(found):
        raise ModelFileError(
            path, f"{int((~found).sum())} of the {what}'s triangles are not in this file: not the same mesh"
        )
    ft_model_c = ft_c[order][pos]
    # undo the model's canonical rotation: corner k of the model face is canonical corner (k - shift) % 3
    inverse = np.argsort(model_cols, axis=1)
    return np.take_along_axis(ft_model_c, inverse, axis=1)
