"""Posed meshes drawn over a photo through the camera of a 2D fit (what the detector saw, and what was fitted).

The camera is a pinhole in OpenCV's convention, such as the ``camera`` of a
:func:`smplcore.fit.fit_keypoints` result (any object with ``focal`` (2,), ``center`` (2,), ``rotation``
(3, 3), ``translation`` (3,) and, optionally, ``image_size``): a world point ``X`` is seen at
``R X + t`` (x right, y down, z forward) and projected with the focal lengths and the principal point, in
pixels of the image. The meshes are rendered with pyrender through exactly that projection (no framing,
no turning: what lines up in the image lines up with the keypoints) and blended over the image.
:func:`side_view` renders the same meshes from beside the camera, which shows what the image cannot
(depth: a limb in front of or behind the body).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.mesh_args import as_array, check_faces, check_points
from smplcore.render.offscreen import _AMBIENT, _check_rgb, _check_size, _import_pyrender, _open_renderer, save_png

__all__ = ["render_overlay", "save_overlay", "side_view"]

#: (direction the light comes from in camera axes, x right, y down, z forward; intensity)
_CAMERA_LIGHTS = (((-0.5, -1.0, -1.0), 2.6), ((0.8, 0.0, -0.6), 1.0), ((0.0, -0.5, 1.0), 0.8))


def _camera_arrays(camera: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """focal (2,), center (2,), rotation (3, 3), translation (3,) of a fit camera, checked."""
    try:
        focal, center = np.asarray(camera.focal, np.float64), np.asarray(camera.center, np.float64)
        rotation = np.asarray(camera.rotation, np.float64)
        translation = np.asarray(camera.translation, np.float64)
    except AttributeError as exc:
        raise TypeError(
            "camera: expected a smplcore.fit.Camera (focal, center, rotation, translation), "
            f"got {type(camera).__name__}"
        ) from exc
    focal = np.broadcast_to(focal, (2,)) if focal.size in (1, 2) else focal
    if focal.shape != (2,) or center.shape != (2,) or rotation.shape != (3, 3) or translation.shape != (3,):
        raise ShapeError("camera: expected focal (2,), center (2,), rotation (3, 3) and translation (3,)")
    return focal, center, rotation, translation


def _background(image: Any, camera: Any, width: int | None, height: int | None) -> np.ndarray:
    """The (H, W, 3) uint8 image drawn on: ``image`` (an array or an image file), or a white canvas of
    ``width`` x ``height`` (default the camera's ``image_size``)."""
    if image is None:
        size = getattr(camera, "image_size", None)
        w = width if width is not None else (None if size is None else int(round(size[0])))
        h = height if height is not None else (None if size is None else int(round(size[1])))
        if w is None or h is None:
            raise ValueError("image: without an image, give width and height (or a camera with image_size)")
        return np.full((_check_size("height", h), _check_size("width", w), 3), 255, np.uint8)
    if isinstance(image, (str, os.PathLike)):
        from smplcore._deps import require

        Image = require("PIL.Image", "render_overlay", "render")
        path = Path(image)
        if not path.is_file():
            raise FileNotFoundError(f"image: {path}: no such file")
        with Image.open(path) as img:
            image = np.asarray(img.convert("RGB"))
    arr = as_array("image", image)
    if arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=2)
    if arr.ndim != 3 or arr.shape[2] not in (3, 4):
        raise ShapeError(f"image: expected shape (H, W), (H, W, 3) or (H, W, 4), got {tuple(arr.shape)}")
    if arr.dtype != np.uint8:
        raise ValueError(f"image: expected dtype uint8 (0-255), got {arr.dtype}")
    _check_size("image height", arr.shape[0])
    _check_size("image width", arr.shape[1])
    return np.ascontiguousarray(arr[..., :3])


def _render_camera_space(points_cam: np.ndarray, tris: np.ndarray, focal, center, width, height, colors):
    """RGBA (H, W, 4) float in [0, 1] and the coverage mask of meshes given in OpenCV camera axes."""
    pyrender, trimesh = _import_pyrender()
    flip = np.array([1.0, -1.0, -1.0])  # OpenCV (y down, z forward) -> OpenGL (y up, looking down -z)
    depth = points_cam[..., 2]
    front = depth[depth > 0]
    if front.size == 0:
        return np.zeros((height, width, 4)), np.zeros((height, width), bool)
    znear, zfar = max(float(front.min()) * 0.5, 1e-3), float(depth.max()) * 2.0 + 1.0
    scene = pyrender.Scene(bg_color=np.zeros(4), ambient_light=np.full(3, _AMBIENT))
    for i in range(len(points_cam)):
        material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=colors[i], metallicFactor=0.0, roughnessFactor=0.65, alphaMode="OPAQUE", doubleSided=True
        )
        tm = trimesh.Trimesh(vertices=points_cam[i] * flip, faces=tris, process=False, validate=False)
        scene.add(pyrender.Mesh.from_trimesh(tm, material=material, smooth=True))
    cam = pyrender.IntrinsicsCamera(fx=focal[0], fy=focal[1], cx=center[0], cy=center[1], znear=znear, zfar=zfar)
    scene.add(cam, pose=np.eye(4))
    for direction, intensity in _CAMERA_LIGHTS:
        d = np.asarray(direction, np.float64) * flip
        z = d / np.linalg.norm(d)  # the light shines along -z of its pose: from `direction` towards the scene
        x = np.cross([0.0, 1.0, 0.0], z)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, np.cross(z, x), z
        scene.add(pyrender.DirectionalLight(color=np.ones(3), intensity=intensity), pose=pose)
    renderer = None
    try:
        renderer = _open_renderer(pyrender, width, height)
        rgb, zbuf = renderer.render(scene)
    finally:
        if renderer is not None:
            renderer.delete()
    mask = zbuf > 0
    return np.concatenate([rgb[..., :3] / 255.0, mask[..., None]], axis=-1), mask


def render_overlay(
    image: Any,
    vertices: Any,
    faces: Any,
    camera: Any,
    *,
    color: Any = (0.55, 0.75, 0.95),
    alpha: float = 0.6,
    keypoints: Any = None,
    keypoint_color: Any = (0.9, 0.15, 0.1),
    width: int | None = None,
    height: int | None = None,
) -> np.ndarray:
    """Draw meshes over ``image`` as ``camera`` sees them; returns an (H, W, 3) uint8 image.

    Args:
        image: the photo, an (H, W, 3|4) uint8 array or an image file; None draws on a white canvas of
            ``width`` x ``height`` (default the camera's ``image_size``).
        vertices: (V, 3) or (N, V, 3) world positions (the fit's world: ``model(**result.params).vertices``).
        faces: (F, 3) triangle indices shared by the meshes.
        camera: the fit's camera (``result.camera``, a :class:`smplcore.fit.Camera`).
        color: RGB floats in [0, 1], or (N, 3) one per mesh.
        alpha: the meshes' opacity over the image, in [0, 1].
        keypoints: optional (K, 2|3) or (N, K, 2|3) pixels (with confidence: points below 0.1 are not
            drawn) drawn as dots, e.g. the detections that were fitted.
        keypoint_color: RGB floats in [0, 1] of the dots.

    Raises:
        ValueError / ShapeError: a bad argument (named). RuntimeError: no offscreen OpenGL context.
    """
    verts = check_points("vertices", vertices, "(V, 3) or (N, V, 3)")
    if verts.ndim == 2:
        verts = verts[None]
    tris = check_faces(faces, verts.shape[1])
    focal, center, rotation, translation = _camera_arrays(camera)
    base = _background(image, camera, width, height)
    h, w = base.shape[:2]
    colors = _check_rgb("color", color, len(verts), allow_alpha=False)
    colors = np.repeat(colors, len(verts), axis=0) if len(colors) == 1 else colors
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise ValueError(f"alpha: expected a number in [0, 1], got {alpha!r}") from None
    if not 0.0 <= a <= 1.0:
        raise ValueError(f"alpha: expected a number in [0, 1], got {alpha!r}")
    rgba, mask = _render_camera_space(verts @ rotation.T + translation, tris, focal, center, w, h, colors)
    out = base.astype(np.float64) / 255.0
    out[mask] = (1 - a) * out[mask] + a * rgba[mask, :3]
    out = np.clip(np.round(out * 255), 0, 255).astype(np.uint8)
    if keypoints is not None:
        out = _draw_points(out, keypoints, _check_rgb("keypoint_color", keypoint_color, None, False)[0, :3])
    return out


def _draw_points(image: np.ndarray, keypoints: Any, rgb: np.ndarray) -> np.ndarray:
    """``image`` with dots at the (…, K, 2|3) pixels (confidence ≥ 0.1 where given)."""
    pts = as_array("keypoints", keypoints).astype(np.float64)
    if pts.ndim < 2 or pts.shape[-1] not in (2, 3):
        raise ShapeError(f"keypoints: expected (K, 2|3) or (N, K, 2|3) pixels, got {tuple(pts.shape)}")
    pts = pts.reshape(-1, pts.shape[-1])
    keep = np.all(np.isfinite(pts[:, :2]), axis=1) & ((pts[:, 2] >= 0.1) if pts.shape[1] == 3 else True)
    h, w = image.shape[:2]
    radius = max(2, int(round(0.006 * max(h, w))))
    yy, xx = np.mgrid[-radius : radius + 1, -radius : radius + 1]
    disc = xx**2 + yy**2 <= radius**2
    out = image.copy()
    colour = np.round(rgb * 255).astype(np.uint8)
    for x, y in pts[keep, :2]:
        cx, cy = int(round(x)), int(round(y))
        ys, xs = cy + yy[disc], cx + xx[disc]
        inside = (ys >= 0) & (ys < h) & (xs >= 0) & (xs < w)
        out[ys[inside], xs[inside]] = colour
    return out


def side_view(
    vertices: Any,
    faces: Any,
    camera: Any,
    *,
    angle: float = 90.0,
    color: Any = (0.55, 0.75, 0.95),
    width: int = 600,
    height: int = 600,
    up: Any = (0.0, -1.0, 0.0),
) -> np.ndarray:
    """The meshes as seen from beside ``camera``: turned by ``angle`` degrees about the vertical axis
    through their centre (``up``, in the camera's axes: its −y, the image's up, by default), framed to fit;
    an (H, W, 3) uint8 image on white. What leans towards the camera in the fit leans sideways here."""
    verts = check_points("vertices", vertices, "(V, 3) or (N, V, 3)")
    if verts.ndim == 2:
        verts = verts[None]
    tris = check_faces(faces, verts.shape[1])
    _, _, rotation, translation = _camera_arrays(camera)
    cam_pts = verts @ rotation.T + translation
    u = np.asarray(up, np.float64)
    u = u / np.linalg.norm(u)
    centre = cam_pts.reshape(-1, 3).mean(0)
    a = math.radians(float(angle))
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    turn = np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * k @ k  # Rodrigues about u
    turned = (cam_pts - centre) @ turn.T
    extent = np.abs(turned[..., :2]).max() * 1.15 + 1e-6
    width, height = _check_size("width", width), _check_size("height", height)
    f = 0.5 * min(width, height) * 4.0 / extent  # seen from 4 extents away, filling the image
    turned[..., 2] += 4.0 * extent
    colors = _check_rgb("color", color, len(verts), allow_alpha=False)
    colors = np.repeat(colors, len(verts), axis=0) if len(colors) == 1 else colors
    rgba, mask = _render_camera_space(turned, tris, (f, f), (width / 2, height / 2), width, height, colors)
    out = np.ones((height, width, 3))
    out[mask] = rgba[mask, :3]
    return np.clip(np.round(out * 255), 0, 255).astype(np.uint8)


def save_overlay(path: str | os.PathLike, image: Any, vertices: Any, faces: Any, camera: Any, **kwargs: Any) -> Path:
    """:func:`render_overlay` written to ``path`` (.png); returns the path."""
    out = Path(path)
    if out.suffix.lower() != ".png":
        raise ValueError(f"path: expected a file name ending in .png, got {str(out)!r}")
    return save_png(render_overlay(image, vertices, faces, camera, **kwargs), out)
