"""Headless rendering of posed meshes to images with pyrender (EGL or OSMesa).

Everything here takes plain NumPy arrays: ``vertices`` (V, 3) in metres with Y up and the body
facing +Z, or a batch (N, V, 3) drawn side by side, and ``faces`` (F, 3) integer indices.

pyrender and PyOpenGL are imported only when something is rendered. Before that import the
OpenGL platform is chosen through ``PYOPENGL_PLATFORM`` (``os.environ.setdefault``, so a value
set by the user wins): ``egl`` when an EGL library is found, otherwise ``osmesa`` when an OSMesa
library is found, otherwise ``egl`` (which then fails with a message on how to fix it).
"""

from __future__ import annotations

import ctypes.util
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ShapeError as _ShapeError
from smplcore.mesh_args import as_array, check_faces, check_points

__all__ = ["CAMERAS", "render_mesh", "render_to_png", "save_png"]

#: The supported ``camera`` values and the angle (degrees) the camera is turned about the
#: vertical axis from straight in front of the body (+Z) towards its left side (+X).
CAMERAS: dict[str, float] = {"front": 0.0, "three_quarter": 45.0, "side": 90.0}

_CONTEXT_FAILURE = "could not create an offscreen OpenGL context"
_MAX_SIZE = 8192
# Fraction of the half field of view the framed bounding box may fill (the rest is margin).
_FILL = 0.85
# Gap between neighbouring meshes of a batch, as a fraction of the widest mesh.
_GAP = 0.15
# Lights fixed to the camera (which looks down -Z): (direction the light comes from, RGB,
# intensity). A warm key from the upper left, a cool fill from the right, a rim from behind.
_LIGHTS = (
    ((-1.0, 1.0, 1.0), (1.0, 0.97, 0.92), 2.8),
    ((1.0, 0.0, 0.5), (0.9, 0.95, 1.0), 0.9),
    ((0.3, 1.0, -1.2), (1.0, 1.0, 1.0), 1.0),
)
_AMBIENT = 0.25


# ---------------------------------------------------------------------------------------------
# input checking
# ---------------------------------------------------------------------------------------------


def _check_rgb(name: str, value: Any, count: int | None, allow_alpha: bool) -> np.ndarray:
    """Colour(s) as floats in [0, 1]: (3,)/(4,) or, when ``count`` is given, also (count, 3|4).

    Returns an array of shape (count or 1, 4) with alpha 1 where none was given.
    """
    arr = as_array(name, value)
    sizes = (3, 4) if allow_alpha else (3,)
    expected = "(3,) or (4,)" if allow_alpha else "(3,)"
    if count is not None:
        expected += f" or (N={count}, {'3|4' if allow_alpha else '3'})"
    ok = (arr.ndim == 1 and arr.shape[0] in sizes) or (
        count is not None and arr.ndim == 2 and arr.shape[0] == count and arr.shape[1] in sizes
    )
    if not ok:
        raise _ShapeError(f"{name}: expected shape {expected}, got {tuple(arr.shape)}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name}: expected numbers in [0, 1], got dtype {arr.dtype}")
    arr = arr.astype(np.float64)
    if not np.all(np.isfinite(arr)) or arr.min() < 0.0 or arr.max() > 1.0:
        raise ValueError(f"{name}: expected values in [0, 1] (floats, not 0-255), got {arr.tolist()}")
    arr = np.atleast_2d(arr)
    if arr.shape[1] == 3:
        arr = np.concatenate([arr, np.ones((arr.shape[0], 1))], axis=1)
    return arr


def _check_size(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name}: expected an integer number of pixels, got {value!r}")  # noqa: TRY004
    if not 1 <= int(value) <= _MAX_SIZE:
        raise ValueError(f"{name}: expected 1 to {_MAX_SIZE} pixels, got {int(value)}")
    return int(value)


# ---------------------------------------------------------------------------------------------
# scene geometry (pure NumPy)
# ---------------------------------------------------------------------------------------------


def _rotation_y(angle_deg: float) -> np.ndarray:
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _look_at(eye: np.ndarray, target: np.ndarray, up: Sequence[float] = (0.0, 1.0, 0.0)) -> np.ndarray:
    """Pose (4, 4) of a camera/light at ``eye`` whose -Z axis points at ``target`` (OpenGL)."""
    z = np.asarray(eye, dtype=np.float64) - np.asarray(target, dtype=np.float64)
    z /= np.linalg.norm(z)
    x = np.cross(np.asarray(up, dtype=np.float64), z)
    if np.linalg.norm(x) < 1e-9:  # looking straight along ``up``
        x = np.cross(np.array([0.0, 0.0, 1.0]), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, y, z, eye
    return pose


def _layout(verts: np.ndarray, joints: np.ndarray | None, angle_deg: float) -> tuple[np.ndarray, np.ndarray | None]:
    """Turn each mesh so the camera (looking down -Z) sees it from ``angle_deg`` and lay the
    meshes of a batch out left to right along X, centred on x = 0.

    The camera turning towards the body's left (+X) is the same as turning each body by
    -angle about its own vertical axis through its bounding-box centre; heights (Y) are kept.
    """
    rot = _rotation_y(-angle_deg)
    lo, hi = verts.min(axis=1), verts.max(axis=1)  # (N, 3)
    pivot = 0.5 * (lo + hi)
    pivot[:, 1] = 0.0
    out = (verts - pivot[:, None]) @ rot.T
    jout = None if joints is None else (joints - pivot[:, None]) @ rot.T
    n = verts.shape[0]
    if n > 1:
        lo_x, hi_x = out[..., 0].min(axis=1), out[..., 0].max(axis=1)
        widths = hi_x - lo_x
        step = max(float(widths.max()), 1e-6) * (1.0 + _GAP)
        shift = (np.arange(n) - 0.5 * (n - 1)) * step - 0.5 * (lo_x + hi_x)
        out = out.copy()
        out[..., 0] += shift[:, None]
        if jout is not None:
            jout = jout.copy()
            jout[..., 0] += shift[:, None]
    return out, jout


def _frame(lo: np.ndarray, hi: np.ndarray, yfov: float, aspect: float) -> tuple[np.ndarray, float, float, float]:
    """Camera on +Z looking down -Z at the box centre, far enough that the whole box [lo, hi]
    projects inside ``_FILL`` of the image in both directions. Returns (pose, distance, znear, zfar).
    """
    center = 0.5 * (lo + hi)
    half = np.maximum(0.5 * (hi - lo), 1e-6)
    tan_y = math.tan(0.5 * yfov) * _FILL
    tan_x = math.tan(0.5 * yfov) * aspect * _FILL
    # A corner at (dx, dy, dz) from the centre is at depth distance - dz from the camera; it
    # fits when |dx| <= tan_x * (distance - dz), i.e. distance >= |dx| / tan_x + dz. The worst
    # corner is the one nearest the camera (dz = +half_z).
    dist = max(half[0] / tan_x, half[1] / tan_y) + half[2]
    dist = max(dist, 2.0 * half[2] + 1e-3)
    eye = center + np.array([0.0, 0.0, dist])
    znear = max((dist - half[2]) * 0.5, 1e-4)
    zfar = (dist + half[2]) * 2.0 + 1e-3
    return _look_at(eye, center), dist, znear, zfar


# ---------------------------------------------------------------------------------------------
# OpenGL / pyrender
# ---------------------------------------------------------------------------------------------


def _choose_platform() -> None:
    if "PYOPENGL_PLATFORM" in os.environ:
        return
    if "OpenGL" in sys.modules:
        # PyOpenGL already picked its platform; pyrender would then mismatch. Still default to
        # EGL and let context creation report the problem.
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        return
    if ctypes.util.find_library("EGL") is None and ctypes.util.find_library("OSMesa") is not None:
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
    else:
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def _import_pyrender():
    _choose_platform()  # must happen before pyrender / OpenGL are imported
    try:
        import pyrender
        import trimesh
    except ModuleNotFoundError as exc:
        from smplcore._deps import missing

        raise missing(exc.name or "pyrender", "rendering", "render", str(exc)) from None
    except Exception as exc:  # PyOpenGL raises ImportError & co. when the platform library is missing
        raise RuntimeError(_context_help(exc)) from exc
    return pyrender, trimesh


def _context_help(exc: BaseException) -> str:
    platform = os.environ.get("PYOPENGL_PLATFORM", "<unset>")
    return (
        f"{_CONTEXT_FAILURE} (PYOPENGL_PLATFORM={platform}): {type(exc).__name__}: {exc}. "
        "To fix: install Mesa's EGL (Debian/Ubuntu: `apt-get install libegl1 libgl1-mesa-dri`) "
        "and use PYOPENGL_PLATFORM=egl, or install OSMesa (`apt-get install libosmesa6`) and set "
        "PYOPENGL_PLATFORM=osmesa before Python starts. A PYOPENGL_PLATFORM you set is kept as it "
        "is; unset it to let smplcore choose egl (or osmesa when only OSMesa is installed)."
    )


def _open_renderer(pyrender: Any, width: int, height: int):
    try:
        return pyrender.OffscreenRenderer(viewport_width=width, viewport_height=height)
    except Exception as exc:
        raise RuntimeError(_context_help(exc)) from exc


def render_mesh(
    vertices: Any,
    faces: Any,
    *,
    width: int = 800,
    height: int = 800,
    color: Any = (0.65, 0.74, 0.86),
    background: Any = (1, 1, 1),
    camera: str = "front",
    yfov_deg: float = 30,
    joints: Any = None,
    joint_color: Any = (0.85, 0.2, 0.15),
    joint_radius: float | None = None,
    alpha: float | None = None,
    smooth: bool = True,
    uv: tuple[Any, Any] | None = None,
    texture: Any = None,
) -> np.ndarray:
    """Render a mesh, or a batch of meshes side by side, to an (height, width, 3) uint8 image.

    Args:
        vertices: (V, 3) vertex positions in metres (Y up, body facing +Z), or (N, V, 3) for N
            meshes drawn left to right in one image (gap of 15% of the widest mesh).
        faces: (F, 3) integer vertex indices, shared by every mesh of a batch.
        width, height: image size in pixels.
        color: mesh colour, RGB or RGBA floats in [0, 1]; for a batch also (N, 3|4), one per mesh.
        background: RGB floats in [0, 1].
        camera: ``"front"`` (from +Z), ``"side"`` (from the body's left, +X) or
            ``"three_quarter"`` (45 degrees between the two). The camera is auto-framed so every
            mesh's bounding box (and the joint spheres) fits with a margin.
        yfov_deg: vertical field of view in degrees, in (0, 180).
        joints: optional (J, 3) joint positions (or (N, J, 3) for a batch), drawn as small spheres.
        joint_color: RGB(A) floats in [0, 1] of the joint spheres.
        joint_radius: sphere radius in metres; default 1.5% of the largest mesh bounding-box
            diagonal (about 2.7 cm for a 1.7 m body).
        alpha: mesh opacity in [0, 1]; default 1, or 0.5 when ``joints`` are given so that the
            joints inside the body show through. An alpha in ``color`` is used when this is None
            and no joints are given.
        smooth: smooth shading from vertex normals (True) or flat shading per face (False).
        uv: optional UV map ``(vt, ft)`` (T, 2) and (F, 3) of the mesh (a model's:
            :func:`smplcore.uv.model_uv`), needed for ``texture``.
        texture: optional base-colour image drawn on every mesh through ``uv`` (``color`` is then not
            used): an image file, an (H, W, 3|4) uint8 array or ``"uv-grid"``
            (:func:`smplcore.uv.uv_grid_texture`).

    Returns:
        np.ndarray of shape (height, width, 3), dtype uint8, first row at the top.

    Raises:
        ValueError: a bad argument (the message names it, with the expected and received shape).
        RuntimeError: no offscreen OpenGL context could be created (the message says how to fix it).
    """
    verts = check_points("vertices", vertices, "(V, 3) or (N, V, 3)")
    batched = verts.ndim == 3
    if not batched:
        verts = verts[None]
    n, num_v = verts.shape[0], verts.shape[1]
    tris = check_faces(faces, num_v)
    width = _check_size("width", width)
    height = _check_size("height", height)
    colors = _check_rgb("color", color, n if batched else None, allow_alpha=True)
    if colors.shape[0] == 1:
        colors = np.repeat(colors, n, axis=0)
    bg = _check_rgb("background", background, None, allow_alpha=False)[0]
    if not isinstance(camera, str) or camera not in CAMERAS:
        raise ValueError(f"camera: expected one of {sorted(CAMERAS)}, got {camera!r}")
    try:
        yfov = float(yfov_deg)
    except (TypeError, ValueError):
        raise ValueError(f"yfov_deg: expected a number of degrees in (0, 180), got {yfov_deg!r}") from None
    if not 0.0 < yfov < 180.0:
        raise ValueError(f"yfov_deg: expected a number of degrees in (0, 180), got {yfov_deg!r}")

    jts = None
    if joints is not None:
        jts = check_points("joints", joints, "(N, J, 3)" if batched else "(J, 3)")
        if jts.ndim != verts.ndim - (0 if batched else 1) or (batched and jts.shape[0] != n):
            expected = f"(N={n}, J, 3) to match vertices {tuple(verts.shape)}" if batched else "(J, 3)"
            raise _ShapeError(f"joints: expected shape {expected}, got {tuple(jts.shape)}")
        if not batched:
            jts = jts[None]
        jcolor = _check_rgb("joint_color", joint_color, None, allow_alpha=True)[0]
    if alpha is not None:
        try:
            alpha = float(alpha)
        except (TypeError, ValueError):
            raise ValueError(f"alpha: expected a number in [0, 1], got {alpha!r}") from None
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(f"alpha: expected a number in [0, 1], got {alpha!r}")
        colors[:, 3] = alpha
    elif jts is not None:
        colors[:, 3] = 0.5

    split = image = None
    if texture is not None:
        from smplcore.uv import resolve_texture, split_seams

        if uv is None or not (isinstance(uv, (tuple, list)) and len(uv) == 2):
            raise ValueError("uv: a texture needs the mesh's UV map, uv=(vt, ft) (e.g. smplcore.uv.model_uv)")
        split = split_seams(tris, uv[0], uv[1])
        image = resolve_texture(texture)

    placed, placed_joints = _layout(verts, jts, CAMERAS[camera])

    radius = 0.0
    if placed_joints is not None:
        if joint_radius is None:
            diag = np.linalg.norm(verts.max(axis=1) - verts.min(axis=1), axis=1).max()
            radius = 0.015 * float(diag) if diag > 0 else 0.01
        else:
            try:
                radius = float(joint_radius)
            except (TypeError, ValueError):
                raise ValueError(f"joint_radius: expected a positive number of metres, got {joint_radius!r}") from None
            if not (math.isfinite(radius) and radius > 0.0):
                raise ValueError(f"joint_radius: expected a positive number of metres, got {joint_radius!r}")

    lo = placed.reshape(-1, 3).min(axis=0)
    hi = placed.reshape(-1, 3).max(axis=0)
    if placed_joints is not None:
        pj = placed_joints.reshape(-1, 3)
        lo = np.minimum(lo, pj.min(axis=0) - radius)
        hi = np.maximum(hi, pj.max(axis=0) + radius)
    cam_pose, _dist, znear, zfar = _frame(lo, hi, math.radians(yfov), width / height)

    pyrender, trimesh = _import_pyrender()

    scene = pyrender.Scene(bg_color=np.append(bg[:3], 1.0), ambient_light=np.full(3, _AMBIENT))
    for i in range(n):
        if split is not None and image is not None:  # set together
            from smplcore.render.texture import textured_mesh

            scene.add(textured_mesh(pyrender, trimesh, placed[i], tris, split, image, colors[i, 3], smooth))
            continue
        rgba = colors[i]
        blend = rgba[3] < 1.0
        material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=rgba,
            metallicFactor=0.0,
            roughnessFactor=0.65,
            alphaMode="BLEND" if blend else "OPAQUE",
            doubleSided=not blend,
        )
        tm = trimesh.Trimesh(vertices=placed[i], faces=tris, process=False, validate=False)
        scene.add(pyrender.Mesh.from_trimesh(tm, material=material, smooth=smooth))

    if placed_joints is not None and placed_joints.shape[1] > 0:
        sphere = trimesh.creation.icosphere(subdivisions=2, radius=radius)
        poses = np.tile(np.eye(4), (placed_joints.shape[0] * placed_joints.shape[1], 1, 1))
        poses[:, :3, 3] = placed_joints.reshape(-1, 3)
        jmaterial = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=jcolor, metallicFactor=0.0, roughnessFactor=0.5, alphaMode="OPAQUE"
        )
        scene.add(pyrender.Mesh.from_trimesh(sphere, material=jmaterial, poses=poses, smooth=True))

    cam = pyrender.PerspectiveCamera(yfov=math.radians(yfov), znear=znear, zfar=zfar, aspectRatio=width / height)
    scene.add(cam, pose=cam_pose)

    target = 0.5 * (lo + hi)
    for offset, rgb, intensity in _LIGHTS:
        light = pyrender.DirectionalLight(color=np.asarray(rgb), intensity=intensity)
        scene.add(light, pose=_look_at(target + np.asarray(offset), target))

    renderer = None
    try:
        renderer = _open_renderer(pyrender, width, height)
        color_img, _depth = renderer.render(scene)
    finally:
        if renderer is not None:
            renderer.delete()
    img = np.ascontiguousarray(color_img[..., :3], dtype=np.uint8)
    return img


# ---------------------------------------------------------------------------------------------
# PNG output
# ---------------------------------------------------------------------------------------------


def save_png(image: Any, path: str | os.PathLike) -> Path:
    """Write an image to ``path`` as PNG (parent folders are created) and return the path.

    ``image`` is uint8 (H, W), (H, W, 3) or (H, W, 4), e.g. what :func:`render_mesh` returns.
    """
    from smplcore._deps import require

    Image = require("PIL.Image", "save_png", "render")
    arr = as_array("image", image)
    if not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] in (3, 4))) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise _ShapeError(f"image: expected shape (H, W), (H, W, 3) or (H, W, 4), got {tuple(arr.shape)}")
    if arr.dtype != np.uint8:
        raise ValueError(f"image: expected dtype uint8, got {arr.dtype}")
    out = Path(path)
    if out.suffix.lower() != ".png":
        raise ValueError(f"path: expected a file name ending in .png, got {str(out)!r}")
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.ascontiguousarray(arr)).save(out, format="PNG")
    return out


def render_to_png(path: str | os.PathLike, vertices: Any, faces: Any, **kwargs: Any) -> Path:
    """:func:`render_mesh` (same keyword arguments) and :func:`save_png` in one call; returns the path.

    The path comes first, as in :func:`smplcore.export.save_mesh` and :func:`smplcore.export.save_glb`.
    The earlier order ``render_to_png(vertices, faces, path)`` still works (a path is never an array, so the
    two cannot be confused) and warns with a ``DeprecationWarning``.
    """
    if not _is_path(path) and _is_path(faces):
        from smplcore.errors import warn

        warn(
            "render_to_png(vertices, faces, path) is deprecated: pass the path first, "
            "render_to_png(path, vertices, faces), as save_mesh and save_glb take it",
            DeprecationWarning,
        )
        path, vertices, faces = faces, path, vertices
    elif not _is_path(path):
        raise TypeError(f"path: expected a file name (str or os.PathLike) first, got {type(path).__name__}")
    out = Path(path)
    if out.suffix.lower() != ".png":  # fail before the (slow) render
        raise ValueError(f"path: expected a file name ending in .png, got {str(out)!r}")
    return save_png(render_mesh(vertices, faces, **kwargs), out)


def _is_path(value: Any) -> bool:
    return isinstance(value, (str, os.PathLike))
