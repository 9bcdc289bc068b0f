"""UV maps and textures, shared by the exporters, the renderer and the viewer (``smplcore.export.uv`` is this
module under its former name).

A model's UV map is ``vt`` (T, 2), OBJ convention (v up), and ``ft`` (F, 3) indices into it, corner for
corner with the faces (see :mod:`smplcore.io.uv`). Formats with one index per vertex (glTF, OpenGL) need
the mesh split along the UV seams: :func:`split_seams` gives one vertex per distinct (vertex, UV) pair.

Textures are (H, W, 3|4) uint8 images, first row at the top; :func:`uv_grid_texture` draws a labelled
checker grid that shows how the map lies on the body, :func:`load_texture` reads an image file.
"""

from __future__ import annotations

import colorsys
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.mesh_args import as_array

__all__ = ["SeamSplit", "TextureInput", "load_texture", "model_uv", "resolve_texture", "split_seams", "uv_grid_texture"]

#: What the ``texture`` arguments take: an image file, an (H, W, 3|4) uint8 array, or ``"uv-grid"``.
TextureInput = str | os.PathLike | np.ndarray

UV_GRID = "uv-grid"


@dataclass(frozen=True)
class SeamSplit:
    """A mesh split along its UV seams.

    Attributes
    ----------
    vertex_ids : (N,) int64 original vertex of each split vertex (N >= V; sorted, so split vertices of
        one original vertex are neighbours).
    uv : (N, 2) float64 the UV of each split vertex (OBJ convention, v up).
    faces : (F, 3) int64 the faces over the split vertices (same order and corners as the original).
    """

    vertex_ids: np.ndarray
    uv: np.ndarray
    faces: np.ndarray

    @property
    def num_vertices(self) -> int:
        return int(self.vertex_ids.shape[0])


def check_uv_map(vt: Any, ft: Any, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``vt`` (T, 2) float64 and ``ft`` (F, 3) int64 matching ``faces`` (F, 3); errors name the argument."""
    vt = as_array("vt", vt)
    ft = as_array("ft", ft)
    if vt.ndim != 2 or vt.shape[1] != 2 or vt.shape[0] < 1:
        raise ShapeError(f"vt: expected shape (T, 2), got {tuple(vt.shape)}")
    if not np.issubdtype(vt.dtype, np.number) or not np.all(np.isfinite(vt)):
        raise ValueError("vt: expected finite numbers")
    if ft.shape != faces.shape:
        raise ShapeError(f"ft: expected shape (F={faces.shape[0]}, 3) like faces, got {tuple(ft.shape)}")
    if not np.issubdtype(ft.dtype, np.integer):
        raise ValueError(f"ft: expected an integer array, got dtype {ft.dtype}")
    if ft.size and (ft.min() < 0 or ft.max() >= vt.shape[0]):
        raise ValueError(f"ft: indices must be in [0, {vt.shape[0] - 1}] for {vt.shape[0]} UVs")
    return vt.astype(np.float64, copy=False), ft.astype(np.int64, copy=False)


def split_seams(faces: Any, vt: Any, ft: Any) -> SeamSplit:
    """One vertex per distinct (vertex, UV) pair the faces use: what glTF and OpenGL need.

    Args:
        faces: (F, 3) vertex indices.
        vt: (T, 2) texture coordinates.
        ft: (F, 3) UV indices per face corner.

    Returns:
        :class:`SeamSplit`; vertices no face uses are dropped (they have no UV).
    """
    faces = np.asarray(faces, dtype=np.int64)
    vt, ft = check_uv_map(vt, ft, faces)
    pairs = np.stack([faces.ravel(), ft.ravel()], axis=1)
    unique, inverse = np.unique(pairs, axis=0, return_inverse=True)
    return SeamSplit(
        vertex_ids=unique[:, 0].copy(), uv=vt[unique[:, 1]], faces=inverse.reshape(faces.shape).astype(np.int64)
    )


def model_uv(model: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """``(vt, ft)`` of a model of either front end (its ``rig.uv``), a :class:`smplcore.model.Rig` or a
    :class:`~smplcore.io.ModelData`, or None."""
    uv = getattr(model, "uv", None)  # a front end that exposes the map itself
    if isinstance(uv, tuple) and len(uv) == 2:
        return uv
    rig = model if hasattr(model, "pose_blocks") else getattr(model, "rig", None)
    if rig is not None:
        return None if rig.uv is None else (np.asarray(rig.uv.vt), np.asarray(rig.uv.ft))
    vt, ft = getattr(model, "vt", None), getattr(model, "ft", None)
    if vt is None or ft is None:
        return None
    return np.asarray(vt), np.asarray(ft)


def _check_image(name: str, image: Any) -> np.ndarray:
    arr = as_array(name, image)
    if arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=2)
    if arr.ndim != 3 or arr.shape[2] not in (3, 4) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ShapeError(f"{name}: expected an image of shape (H, W, 3) or (H, W, 4), got {tuple(arr.shape)}")
    if arr.dtype != np.uint8:
        if np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and arr.min() >= 0 and arr.max() <= 1:
            arr = np.round(arr * 255).astype(np.uint8)
        else:
            raise ValueError(f"{name}: expected uint8 pixels (or floats in [0, 1]), got dtype {arr.dtype}")
    return np.ascontiguousarray(arr)


def load_texture(path: str | os.PathLike) -> np.ndarray:
    """An image file (PNG, JPEG, ...) as an (H, W, 3|4) uint8 array (needs Pillow)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"texture: no such image file {str(path)!r}")
    from smplcore._deps import require

    Image = require("PIL.Image", "reading a texture", "export")
    try:
        with Image.open(path) as img:
            mode = "RGBA" if img.mode in ("RGBA", "LA", "P") and "A" in img.getbands() else "RGB"
            return np.asarray(img.convert(mode)).copy()
    except OSError as exc:
        raise ValueError(f"texture: {str(path)!r} is not an image Pillow can read ({exc})") from None


def resolve_texture(texture: TextureInput | None) -> np.ndarray | None:
    """The texture argument of the exporters and the renderer as an (H, W, 3|4) uint8 image, or None."""
    if texture is None:
        return None
    if isinstance(texture, str) and texture == UV_GRID:
        return uv_grid_texture()
    if isinstance(texture, (str, os.PathLike)):
        return load_texture(texture)
    return _check_image("texture", texture)


def encode_png(image: np.ndarray) -> bytes:
    """PNG bytes of an (H, W, 3|4) uint8 image (needs Pillow)."""
    import io

    from smplcore._deps import require

    Image = require("PIL.Image", "writing a texture", "export")
    buf = io.BytesIO()
    Image.fromarray(_check_image("texture", image)).save(buf, format="PNG")
    return buf.getvalue()


def uv_grid_texture(size: int = 1024, cells: int = 8) -> np.ndarray:
    """A UV test texture: ``cells`` x ``cells`` coloured checker squares, thin dark grid lines and
    white labels (column letter A.., row number 1.. counted from the bottom, as v is) in every square.

    Hue follows u and brightness v, so on a textured body one sees at once which part of the map lies
    where, whether it is mirrored (labels read backwards) and how much it is stretched.

    Returns:
        (size, size, 3) uint8, first row at the top (v = 1).
    """
    if not isinstance(size, (int, np.integer)) or not 16 <= int(size) <= 8192:
        raise ValueError(f"size: expected an integer number of pixels in [16, 8192], got {size!r}")
    if not isinstance(cells, (int, np.integer)) or not 1 <= int(cells) <= 26:
        raise ValueError(f"cells: expected an integer in [1, 26], got {cells!r}")
    size, cells = int(size), int(cells)
    centres = (np.arange(size) + 0.5) / size
    u = centres[None, :]
    v = 1.0 - centres[:, None]  # the top row is v = 1
    col = np.minimum((u * cells).astype(int), cells - 1)
    row = np.minimum((v * cells).astype(int), cells - 1)
    hues = np.array([colorsys.hsv_to_rgb(h, 0.55, 1.0) for h in (np.arange(cells) + 0.5) / cells])
    rgb = hues[np.broadcast_to(col, (size, size))]
    shade = 0.55 + 0.45 * (np.broadcast_to(row, (size, size)) + 0.5) / cells
    checker = ((col + row) % 2 == 0) * 0.15 + 0.85
    img = rgb * (shade * checker)[..., None]
    line = max(1, size // 256)
    cell_px = size / cells
    edge = (np.arange(size) % cell_px) < line
    img[edge, :] = 0.15
    img[:, edge] = 0.15
    out = np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)
    try:
        from PIL import Image, ImageDraw, ImageFont
    except ImportError:  # labels need Pillow; the grid alone still shows the map
        return out
    pil = Image.fromarray(out)
    draw = ImageDraw.Draw(pil)
    try:
        font = ImageFont.load_default(size=max(8, int(cell_px * 0.3)))
    except TypeError:  # Pillow < 10.1: fixed-size bitmap font
        font = ImageFont.load_default()
    for c in range(cells):
        for r in range(cells):
            label = f"{chr(65 + c)}{r + 1}"
            x = (c + 0.5) * cell_px
            y = size - (r + 0.5) * cell_px
            draw.text((x, y), label, fill=(255, 255, 255), font=font, anchor="mm")
    return np.asarray(pil).copy()
