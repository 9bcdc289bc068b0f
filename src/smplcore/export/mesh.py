"""Writing posed meshes to OBJ / PLY files, and per-vertex colours from skinning weights.

Takes plain NumPy arrays: ``vertices`` (V, 3) and ``faces`` (F, 3) integer indices. Files are
written through trimesh with ``process=False``, so vertex and face order are kept exactly.
"""

from __future__ import annotations

import colorsys
import os
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ShapeError as _ShapeError
from smplcore.mesh_args import as_array, check_faces, check_points
from smplcore.uv import TextureInput, check_uv_map, encode_png, resolve_texture

__all__ = ["SUPPORTED_SUFFIXES", "save_mesh", "weight_colors"]

#: File suffixes :func:`save_mesh` can write.
SUPPORTED_SUFFIXES = (".obj", ".ply")


def _check_vertices(vertices: Any) -> np.ndarray:
    arr = as_array("vertices", vertices)
    if arr.ndim == 3 and arr.shape[-1] == 3:
        raise _ShapeError(
            f"vertices: expected shape (V, 3), got a batch {tuple(arr.shape)}; save_mesh writes one mesh "
            "per file, e.g. `for i, v in enumerate(vertices): save_mesh(f'mesh_{i}.obj', v, faces)`"
        )
    return check_points("vertices", arr, "(V, 3)", ndims=(2,))


def _check_vertex_colors(vertex_colors: Any, num_vertices: int) -> np.ndarray:
    """(V, 3|4) floats in [0, 1] or uint8 -> (V, 4) uint8."""
    arr = as_array("vertex_colors", vertex_colors)
    if arr.ndim != 2 or arr.shape[0] != num_vertices or arr.shape[1] not in (3, 4):
        raise _ShapeError(
            f"vertex_colors: expected shape (V={num_vertices}, 3) or (V={num_vertices}, 4), got {tuple(arr.shape)}"
        )
    if arr.dtype == np.uint8:
        out = arr
    elif np.issubdtype(arr.dtype, np.floating):
        if not np.all(np.isfinite(arr)) or arr.min() < 0.0 or arr.max() > 1.0:
            raise ValueError(
                "vertex_colors: float colours must be finite and in [0, 1] (pass uint8 for 0-255), "
                f"got values in [{np.nanmin(arr)}, {np.nanmax(arr)}]"
            )
        out = np.round(arr * 255.0).astype(np.uint8)
    else:
        raise ValueError(f"vertex_colors: expected floats in [0, 1] or uint8, got dtype {arr.dtype}")
    if out.shape[1] == 3:
        out = np.concatenate([out, np.full((num_vertices, 1), 255, dtype=np.uint8)], axis=1)
    return np.ascontiguousarray(out)


def save_mesh(
    path: str | os.PathLike,
    vertices: Any,
    faces: Any,
    *,
    vertex_colors: Any = None,
    uv: tuple[Any, Any] | None = None,
    texture: TextureInput | None = None,
) -> Path:
    """Write one mesh to ``path`` as Wavefront OBJ or binary PLY, chosen from the suffix.

    Args:
        path: file to write, ending in ``.obj`` or ``.ply`` (any case); parent folders are created.
        vertices: (V, 3) vertex positions. A batch (N, V, 3) is refused: one mesh per file.
        faces: (F, 3) integer vertex indices in [0, V).
        vertex_colors: optional (V, 3) or (V, 4) colours, floats in [0, 1] or uint8. PLY keeps
            them exactly (as uint8 RGBA); OBJ writes them as the common ``v x y z r g b`` extension.
        uv: optional UV map ``(vt, ft)``: ``vt`` (T, 2) texture coordinates (v up), ``ft`` (F, 3)
            indices into ``vt`` per face corner (a model's, e.g. :func:`smplcore.uv.model_uv`).
            OBJ only: written as ``vt`` lines and ``f v/vt`` faces.
        texture: optional image for the UV map (needs ``uv``, OBJ only): an image file, an
            (H, W, 3|4) uint8 array or ``"uv-grid"`` (:func:`~smplcore.uv.uv_grid_texture`).
            Written as ``<stem>_texture.png`` beside the OBJ, with a ``<stem>.mtl`` whose ``map_Kd`` names it.

    Returns:
        The path written, as a :class:`pathlib.Path`.

    Vertex and face order are kept (trimesh with ``process=False``): reloading with
    ``trimesh.load(path, process=False)`` gives the same arrays. Every vertex is written, but
    trimesh's OBJ reader drops vertices no face uses unless it is given ``maintain_order=True``;
    with a UV map it also splits vertices along the seams unless it is given ``maintain_order=True``.
    """
    out = Path(path)
    suffix = out.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise ValueError(
            f"path: unsupported file suffix {out.suffix!r} in {str(out)!r}; supported: " + ", ".join(SUPPORTED_SUFFIXES)
        )
    verts = _check_vertices(vertices)
    tris = check_faces(faces, verts.shape[0])
    colors = None if vertex_colors is None else _check_vertex_colors(vertex_colors, verts.shape[0])
    if texture is not None and uv is None:
        raise ValueError("texture: a texture needs a UV map; pass uv=(vt, ft), e.g. smplcore.uv.model_uv(model)")
    if uv is not None:
        if suffix != ".obj":
            raise ValueError(f"uv: UV maps are written to .obj files only, got {str(out)!r}")
        if not (isinstance(uv, (tuple, list)) and len(uv) == 2):
            raise ValueError("uv: expected a pair (vt, ft)")
        vt, ft = check_uv_map(uv[0], uv[1], tris)
        image = resolve_texture(texture)
        out.parent.mkdir(parents=True, exist_ok=True)
        _write_textured_obj(out, verts, tris, colors, vt, ft, image)
        return out

    from smplcore._deps import require

    trimesh = require("trimesh", "save_mesh", "export")

    mesh = trimesh.Trimesh(vertices=verts, faces=tris, vertex_colors=colors, process=False, validate=False)
    out.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".obj":
        # Normals are left out: viewers compute them, and a reader that merges v/vn pairs
        # could otherwise reorder vertices. Enough digits to keep float32 round trips exact.
        data = trimesh.exchange.obj.export_obj(
            mesh, include_normals=False, include_color=colors is not None, include_texture=False, digits=9
        )
        out.write_text(data, encoding="utf-8")
    else:
        data = trimesh.exchange.ply.export_ply(mesh, encoding="binary", vertex_normal=False, include_attributes=False)
        out.write_bytes(data)
    return out


def _write_textured_obj(
    out: Path,
    verts: np.ndarray,
    tris: np.ndarray,
    colors: np.ndarray | None,
    vt: np.ndarray,
    ft: np.ndarray,
    image: np.ndarray | None,
) -> None:
    """OBJ with ``vt`` lines and ``f v/vt`` faces (1-based), plus ``.mtl`` and ``.png`` for a texture."""
    lines = ["# written by smplcore"]
    if image is not None:
        material = out.stem
        png = out.with_name(f"{out.stem}_texture.png")
        png.write_bytes(encode_png(image))
        out.with_suffix(".mtl").write_text(
            f"# written by smplcore\nnewmtl {material}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\n"
            f"map_Kd {png.name}\n",
            encoding="utf-8",
        )
        lines.append(f"mtllib {out.with_suffix('.mtl').name}")
    if colors is None:
        lines.extend(f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in verts)
    else:
        rgb = colors[:, :3] / 255.0
        lines.extend(f"v {x:.9g} {y:.9g} {z:.9g} {r:.6g} {g:.6g} {b:.6g}" for (x, y, z), (r, g, b) in zip(verts, rgb))
    lines.extend(f"vt {u:.9g} {v:.9g}" for u, v in vt)
    if image is not None:
        lines.append(f"usemtl {out.stem}")
    f1, t1 = tris + 1, ft + 1
    lines.extend(f"f {a}/{ta} {b}/{tb} {c}/{tc}" for (a, b, c), (ta, tb, tc) in zip(f1.tolist(), t1.tolist()))
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _palette(count: int) -> np.ndarray:
    """``count`` distinct, fixed RGB colours (floats in [0, 1]).

    Hues step by the golden ratio so neighbouring indices (usually neighbouring body parts)
    get far-apart hues; saturation and value cycle so colours that share a hue still differ.
    """
    golden = 0.618033988749895
    sats = (0.75, 0.55, 0.9)
    vals = (0.95, 0.8, 0.65)
    out = np.empty((count, 3))
    for j in range(count):
        hue = (0.05 + j * golden) % 1.0
        out[j] = colorsys.hsv_to_rgb(hue, sats[j % 3], vals[(j // 3) % 3])
    return out


def weight_colors(weights: Any) -> np.ndarray:
    """A colour per vertex from skinning weights, to show which joints move which vertices.

    Each of the J joints gets a fixed, distinct colour (the same for a given J on every call);
    a vertex's colour is the mix of its joints' colours by weight (rows are normalised to sum
    to one; a vertex with no weight is grey).

    Args:
        weights: (V, J) non-negative skinning weights (dense or scipy.sparse).

    Returns:
        (V, 3) uint8 RGB, ready for ``save_mesh(..., vertex_colors=...)``.
    """
    arr = as_array("weights", weights)
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise _ShapeError(f"weights: expected shape (V, J), got {tuple(arr.shape)}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"weights: expected a float array, got dtype {arr.dtype}")
    arr = arr.astype(np.float64, copy=False)
    if not np.all(np.isfinite(arr)):
        raise ValueError("weights: expected finite values, got NaN/inf")
    if arr.min() < -1e-4:
        raise ValueError(f"weights: expected non-negative skinning weights, got a minimum of {arr.min()}")
    w = np.clip(arr, 0.0, None)
    total = w.sum(axis=1, keepdims=True)
    empty = total[:, 0] <= 0.0
    w = w / np.where(total > 0.0, total, 1.0)
    rgb = w @ _palette(arr.shape[1])
    rgb[empty] = 0.5
    return np.round(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)
