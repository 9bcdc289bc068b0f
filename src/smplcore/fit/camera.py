"""A pinhole camera in the OpenCV convention: x right, y down, z forward (into the scene), pixels.

A world point ``X`` is seen at ``X_c = R X + t`` in camera coordinates and projected to
``u = f_x X_c,x / X_c,z + c_x``, ``v = f_y X_c,y / X_c,z + c_y``. SMPL's bodies are Y up and face +Z;
seen by the identity camera a standing body facing the camera therefore has ``global_orient`` ≈ (π, 0, 0)
(:func:`smplcore.fit.fit_keypoints` starts there).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.errors import ShapeError

#: Bounds of a camera's values: beyond them the projections overflow or lose every digit.
MAX_PIXELS = 1e9
MAX_METRES = 1e9


def _finite(value: Any, name: str, shape: tuple[int, ...]) -> np.ndarray:
    if value is None or isinstance(value, (str, bytes)):
        raise TypeError(f"{name}: expected numbers, got {type(value).__name__}")
    try:
        array = np.asarray(value.detach().cpu().numpy() if hasattr(value, "detach") else value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name}: expected numbers, got {type(value).__name__}") from exc
    if array.shape != shape:
        raise ShapeError(f"{name}: expected shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name}: holds NaN or infinite values")
    return array


@dataclass(frozen=True, init=False)
class Camera:
    """A pinhole camera (OpenCV convention).

    Parameters
    ----------
    focal : f (pixels) or (f_x, f_y).
    center : (c_x, c_y) principal point (pixels).
    rotation : (3, 3) world-to-camera rotation R, or an axis-angle (3,); default the identity.
    translation : (3,) world-to-camera translation t (metres); default zero.
    image_size : (width, height) of the image in pixels, or None (unknown). When it is known,
        :func:`smplcore.fit.fit_keypoints` ignores keypoints outside the image (a detector's guesses
        for parts the image cuts off) and tells a body cut by the image's edge from an occluded one.

    Examples
    --------
    >>> import numpy as np
    >>> from smplcore import fit
    >>> cam = fit.Camera(focal=1000.0, center=(320.0, 240.0))
    >>> cam.project(np.array([[0.1, -0.2, 2.0]]))
    array([[370., 140.]])
    """

    focal: np.ndarray  # (2,) f_x, f_y
    center: np.ndarray  # (2,)
    rotation: np.ndarray  # (3, 3)
    translation: np.ndarray  # (3,)
    image_size: tuple[float, float] | None

    def __init__(
        self, focal: Any, center: Any, rotation: Any = None, translation: Any = None, image_size: Any = None
    ) -> None:
        f = _finite(focal, "focal", np.shape(focal) if np.ndim(focal) == 0 else (2,))
        f = np.full(2, float(f)) if f.ndim == 0 else f
        if not np.all(np.isfinite(f)) or np.any(f <= 0) or np.any(f > MAX_PIXELS) or np.any(f < 1 / MAX_PIXELS):
            raise ValueError(f"focal: expected positive focal lengths in pixels (1e-9..1e9), got {f.tolist()}")
        if center is None:
            raise ValueError("center: the principal point (c_x, c_y) in pixels is needed (often the image centre)")
        c = _finite(center, "center", (2,))
        if np.any(np.abs(c) > MAX_PIXELS):
            raise ValueError(f"center: expected a principal point within 1e9 pixels, got {c.tolist()}")
        rot: np.ndarray
        if rotation is None:
            rot = np.eye(3)
        else:
            rot = _finite(rotation, "rotation", np.shape(rotation) if np.shape(rotation) == (3,) else (3, 3))
            if rot.shape == (3,):
                from smplcore.engine import rodrigues

                rot = rodrigues(_finite(rot, "rotation", (3,))[None])[0]
            rot = _finite(rot, "rotation", (3, 3))
            if np.abs(rot @ rot.T - np.eye(3)).max() > 1e-5 or np.linalg.det(rot) < 0:
                raise ValueError("rotation: expected a rotation matrix (orthonormal, determinant +1) or an axis-angle")
        t = np.zeros(3) if translation is None else _finite(translation, "translation", (3,))
        if np.any(np.abs(t) > MAX_METRES):
            raise ValueError(f"translation: expected metres within 1e9, got {t.tolist()}")
        for name, value in (("focal", f), ("center", c), ("rotation", rot), ("translation", t)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "image_size", _image_size(image_size))

    @classmethod
    def from_image_size(cls, width: float, height: float, focal: Any = None) -> Camera:
        """A camera for an image of ``width`` × ``height`` pixels: the principal point at the centre and,
        without ``focal``, the focal length set to the image diagonal (a field of view of about 53°
        across the diagonal — a guess; pass the real focal when it is known)."""
        if not all(isinstance(v, (int, float, np.number)) and not isinstance(v, bool) for v in (width, height)):
            raise TypeError(f"width, height: expected numbers (pixels), got {width!r} x {height!r}")
        if not (np.isfinite(width) and np.isfinite(height) and width > 0 and height > 0):
            raise ValueError(f"width, height: expected a positive image size, got {width} x {height}")
        f = float(np.hypot(width, height)) if focal is None else focal
        return cls(focal=f, center=(width / 2.0, height / 2.0), image_size=(width, height))

    def replace(self, **changes: Any) -> Camera:
        """This camera with some of ``focal``, ``center``, ``rotation``, ``translation``, ``image_size`` changed."""
        values = {k: getattr(self, k) for k in ("focal", "center", "rotation", "translation", "image_size")}
        unknown = sorted(set(changes) - set(values))
        if unknown:
            raise TypeError(f"replace: {unknown} are not camera fields (expected some of {sorted(values)})")
        values.update(changes)
        return Camera(**values)

    def inside(self, pixels: Any, margin: float = 0.0) -> np.ndarray:
        """(...,) whether (..., 2) pixel coordinates lie in the image (``margin`` pixels inside its edges);
        all True when the image size is unknown."""
        uv = np.asarray(pixels, np.float64)
        if self.image_size is None:
            return np.ones(uv.shape[:-1], bool)
        size = np.asarray(self.image_size)
        return np.all((uv >= margin) & (uv <= size - margin), axis=-1)

    def to_camera(self, points: Any) -> np.ndarray:
        """(..., 3) world points in camera coordinates ``R X + t``."""
        if isinstance(points, (str, bytes)):
            raise TypeError(f"points: expected (..., 3) numbers, got {type(points).__name__}")
        try:
            x = np.asarray(points, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"points: expected (..., 3) numbers, got {type(points).__name__}") from exc
        if x.shape[-1:] != (3,):
            raise ShapeError(f"points: expected shape (..., 3), got {x.shape}")
        return x @ self.rotation.T + self.translation

    def project(self, points: Any) -> np.ndarray:
        """(..., 2) pixel coordinates of (..., 3) world points (points behind the camera give
        meaningless values; check ``to_camera(points)[..., 2] > 0``)."""
        xc = self.to_camera(points)
        z = xc[..., 2:3]
        z = np.where(np.abs(z) < 1e-9, 1e-9, z)
        return xc[..., :2] / z * self.focal + self.center

    def project_jacobian(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (..., 2) of world points (..., 3) and their derivative (..., 2, 3) with respect to
        the world points."""
        xc = self.to_camera(points)
        z = np.maximum(xc[..., 2], 1e-6)
        inv = 1.0 / z
        uv = xc[..., :2] * inv[..., None] * self.focal + self.center
        d = np.zeros((*xc.shape[:-1], 2, 3))
        d[..., 0, 0] = self.focal[0] * inv
        d[..., 1, 1] = self.focal[1] * inv
        d[..., 0, 2] = -self.focal[0] * xc[..., 0] * inv * inv
        d[..., 1, 2] = -self.focal[1] * xc[..., 1] * inv * inv
        return uv, d @ self.rotation

    def __repr__(self) -> str:
        rot = "identity" if np.allclose(self.rotation, np.eye(3)) else "R"
        size = "" if self.image_size is None else f", image_size=({self.image_size[0]:g}, {self.image_size[1]:g})"
        return (
            f"Camera(focal=({self.focal[0]:g}, {self.focal[1]:g}), center=({self.center[0]:g}, {self.center[1]:g}), "
            f"rotation={rot}, translation={tuple(float(v) for v in self.translation)}{size})"
        )


def _image_size(value: Any) -> tuple[float, float] | None:
    """``value`` as a (width, height) in pixels, or None."""
    if value is None:
        return None
    size = _finite(value, "image_size", (2,))
    if np.any(size <= 0) or np.any(size > MAX_PIXELS):
        raise ValueError(f"image_size: expected a positive (width, height) in pixels, got {size.tolist()}")
    return float(size[0]), float(size[1])
