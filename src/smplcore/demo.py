"""The main job: pose a body model, write the mesh and an offscreen rendering.

``smplcore demo`` runs this on the packaged open model, offline and with no registration.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.family.names import SMPL_JOINTS
from smplcore.family.specs import get_spec

# A few body poses in SMPL's skeleton: joint name → axis-angle (radians), in SMPL's frame
# (Y up, the body facing +Z, its left at +X).
NAMED_POSES: dict[str, dict[str, tuple[float, float, float]]] = {
    "t-pose": {},
    "a-pose": {"left_shoulder": (0.0, 0.0, -0.9), "right_shoulder": (0.0, 0.0, 0.9)},
    "walk": {
        "left_hip": (-0.45, 0.0, 0.0),
        "right_hip": (0.35, 0.0, 0.0),
        "right_knee": (0.6, 0.0, 0.0),
        "left_knee": (0.15, 0.0, 0.0),
        "left_shoulder": (0.0, 0.0, -1.2),
        "right_shoulder": (0.0, 0.0, 1.2),
        "left_elbow": (0.0, -0.3, 0.0),
        "right_elbow": (0.0, 0.3, 0.0),
    },
    "wave": {
        "left_shoulder": (0.0, 0.0, -1.25),
        "right_shoulder": (0.0, 0.0, -0.35),
        "right_elbow": (0.0, 0.0, -1.4),
        "spine2": (0.0, 0.0, 0.08),
        "head": (0.0, 0.25, 0.0),
    },
    "squat": {
        "left_hip": (-1.4, 0.0, 0.15),
        "right_hip": (-1.4, 0.0, -0.15),
        "left_knee": (1.9, 0.0, 0.0),
        "right_knee": (1.9, 0.0, 0.0),
        "left_ankle": (-0.4, 0.0, 0.0),
        "right_ankle": (-0.4, 0.0, 0.0),
        "spine1": (0.35, 0.0, 0.0),
        "left_shoulder": (0.0, -1.1, -0.2),
        "right_shoulder": (0.0, 1.1, 0.2),
    },
}
DEFAULT_POSES = ("a-pose", "walk", "wave", "squat")


def body_pose_from_names(rotations: dict[str, tuple[float, float, float]]) -> np.ndarray:
    """(69,) SMPL body pose from joint-name rotations (the root excluded)."""
    pose = np.zeros((23, 3))
    for name, rotvec in rotations.items():
        if name not in SMPL_JOINTS[1:]:
            raise ValueError(f"unknown SMPL joint {name!r}; expected one of {SMPL_JOINTS[1:]}")
        pose[SMPL_JOINTS.index(name) - 1] = rotvec
    return pose.reshape(-1)


def load_pose_file(path: str | Path) -> np.ndarray:
    """Body pose(s) from a ``.npy``/``.npz``/``.txt`` file: (69,), (72,) (root first), or (N, 69|72)."""
    import io

    from smplcore.io import numeric_array, read_arrays, read_text

    path = Path(path)
    if path.suffix in (".npz", ".npy"):
        data = read_arrays(path, "a pose file (.npy or .npz)")
        key = None
        if isinstance(data, Mapping):
            key = next((k for k in ("body_pose", "poses", "pose") if k in data), None)
            if key is None:
                raise ValueError(f"--pose: {path} has none of the keys body_pose, poses, pose ({list(data)})")
            data = data[key]
        pose = numeric_array(path, data, key)
    else:
        text = read_text(path, "a pose file (.txt or .csv)", 64 << 20)
        try:
            pose = np.loadtxt(io.StringIO(text), delimiter=None if path.suffix != ".csv" else ",")
        except ValueError as exc:
            raise ValueError(f"--pose: {path} is not a table of numbers ({exc})") from None
    pose = np.atleast_2d(np.asarray(pose, dtype=np.float64))
    if pose.shape[-1] >= 72:  # a full pose: drop the root (and anything past SMPL's 24 joints)
        pose = pose[:, 3:72]
    if pose.shape[-1] != 69:
        raise ValueError(f"--pose: expected 69 or 72 values per pose in {path}, got {pose.shape[-1]}")
    return pose


@dataclass
class DemoResult:
    mesh_path: Path
    image_path: Path | None
    vertices: np.ndarray
    joints: np.ndarray
    faces: np.ndarray
    texture_path: Path | None = None


def run_demo(
    out_dir: str | Path = "smplcore-demo",
    *,
    poses: list[str] | None = None,
    pose_file: str | Path | None = None,
    betas: list[float] | np.ndarray | None = None,
    model_path: str | Path | None = None,
    model_type: str | None = None,
    gender: str = "neutral",
    ext: str | None = None,
    use_pca: bool | None = None,
    mesh_format: str = "obj",
    render: bool = True,
    width: int = 1200,
    height: int = 500,
    texture: str | Path | None = "uv-grid",
    age: float | None = None,
) -> DemoResult:
    """Pose the model and write ``body.{obj,ply}`` (first pose) and ``body.png`` (all poses).

    Parameters
    ----------
    out_dir : output folder (created).
    poses : names from :data:`NAMED_POSES` (default: a-pose, walk, wave, squat).
    pose_file : body poses to use instead of named ones (see :func:`load_pose_file`).
    betas : shape coefficients applied to every pose (default: a spread of shapes, one per pose).
    model_path, model_type, gender, ext : a user's model (default: the packaged open model), found as
        :func:`smplcore.create` finds it (``ext``: the file format to look for first, ``pkl`` or ``npz``).
    use_pca : SMPL+H / SMPL-X: whether hand poses are PCA coefficients (default None: when the file has a
        hand PCA; an AMASS SMPL+H ``.npz`` has none). The demo poses the body only, so this changes nothing
        in the result; it only decides whether a file without a hand PCA can be used.
    mesh_format : ``obj`` or ``ply``.
    render : write the PNG (needs pyrender and an offscreen OpenGL: EGL or OSMesa).
    texture : for a model with a UV map (the open model, SMPL-X): an image file drawn on the body, in the
        rendering and with the OBJ (``body.mtl`` + ``body_texture.png``); ``"uv-grid"`` (default) a generated grid
        that shows how the map lies on the body; None for an untextured body.
    age : the open model at this age in years (1-90; see docs/measure.md); None for the adult model.
    """
    from smplcore.export.mesh import save_mesh
    from smplcore.io.locate import read_model
    from smplcore.numpy_model import BodyModel
    from smplcore.uv import model_uv, resolve_texture

    if mesh_format not in ("obj", "ply"):
        raise ValueError(f"mesh_format: expected 'obj' or 'ply', got {mesh_format!r}")
    if model_path is None and model_type is None:
        model_type = "open"
    data = read_model(model_path, model_type, gender=gender, ext=ext)
    options: dict[str, Any] = {}
    if get_spec(data.model_type).hand_blocks:
        options["use_pca"] = _has_hand_pca(data) if use_pca is None else bool(use_pca)
        if getattr(data, "hands_mean_left", None) is None:
            options["flat_hand_mean"] = True  # no mean hand pose in the file (AMASS's): flat, without a warning
    if age is not None:
        options["age"] = float(age)
    model = BodyModel(data=data, **options)
    if model.model_type not in ("smpl", "open", "smplh", "smplx"):
        raise ValueError(f"the demo poses bodies; a {model.model_type!r} model has no SMPL body pose")
    if pose_file is not None:
        body = load_pose_file(pose_file)
    else:
        names = list(poses or DEFAULT_POSES)
        unknown = [n for n in names if n not in NAMED_POSES]
        if unknown:
            raise ValueError(f"poses: unknown {unknown}; choose from {sorted(NAMED_POSES)}")
        body = np.stack([body_pose_from_names(NAMED_POSES[n]) for n in names])
    count = body.shape[0]
    shape = _demo_betas(betas, count, model.num_betas)
    params: dict[str, Any] = {"betas": shape}
    if model.model_type in ("smpl", "open"):
        params["body_pose"] = body
    else:  # SMPL+H / SMPL-X: the first 21 body joints; SMPL's hand joints have no counterpart
        params["body_pose"] = body[:, : 21 * 3]
    out = model(**params)
    vertices = out.vertices
    assert vertices is not None  # return_verts is on
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    uv = model_uv(model)
    image = resolve_texture(texture) if uv is not None else None
    textured = {"uv": uv, "texture": image} if image is not None else {}
    obj_uv: dict[str, Any] = {"uv": uv, "texture": image} if mesh_format == "obj" and uv is not None else {}
    mesh_path = save_mesh(out_dir / f"body.{mesh_format}", vertices[0], model.faces, **obj_uv)
    texture_path = out_dir / "body_texture.png" if obj_uv and image is not None else None
    image_path = None
    if render:
        from smplcore.render import render_to_png

        image_path = render_to_png(
            out_dir / "body.png",
            _spread_on_floor(vertices),
            model.faces,
            width=width,
            height=height,
            camera="three_quarter",
            **textured,
        )
    return DemoResult(
        Path(mesh_path),
        None if image_path is None else Path(image_path),
        vertices,
        out.joints,
        model.faces,
        texture_path,
    )


def _has_hand_pca(data: Any) -> bool:
    """Whether the model file holds a (non-empty) PCA basis for both hands."""
    comps = [getattr(data, f"hands_components_{side}", None) for side in ("left", "right")]
    return all(c is not None and np.size(c) > 0 for c in comps)


def _demo_betas(betas: Any, count: int, num_betas: int) -> np.ndarray:
    if betas is not None:
        b = np.asarray(betas, dtype=np.float64).reshape(1, -1)
        if b.shape[1] > num_betas:
            raise ValueError(f"betas: the model takes at most {num_betas} shape coefficients, got {b.shape[1]}")
        return np.repeat(b, count, axis=0)
    spread = np.zeros((count, num_betas))
    values = np.linspace(-0.8, 0.8, count) if count > 1 else np.zeros(1)
    spread[:, 0] = values
    if num_betas > 1:
        spread[:, 1] = values[::-1] * 0.8
    return spread


def _spread_on_floor(vertices: np.ndarray) -> np.ndarray:
    """Stand every body on y = 0 (lowest vertex), centred at x = 0, so the renderer's row is level."""
    lifted = vertices - vertices[:, :, 1].min(axis=1)[:, None, None] * np.array([0, 1, 0])
    return lifted - lifted.mean(axis=1, keepdims=True) * np.array([1, 0, 1])
