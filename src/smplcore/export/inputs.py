"""Export inputs: files (AMASS-style motions, parameter sets) read into a Motion or a dict of arrays,
and the coefficient-width checks shared by the rigged exporters. Motions are read by the motion
package's one AMASS reader (:func:`smplcore.motion.motion_from_arrays`)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError, ShapeError, warn

__all__ = ["load_input"]


def _text(value: Any) -> str:
    value = np.asarray(value)
    item = value.item() if value.size == 1 else value
    return item.decode("utf-8", "replace") if isinstance(item, bytes) else str(item)


def _is_text(value: Any) -> bool:
    return isinstance(value, (str, bytes)) or (isinstance(value, np.ndarray) and value.dtype.kind in "SU")


def load_input(path: str | Path, *, fps: float | None = None) -> Any:
    """Read an export input file: an AMASS-style motion ``.npz`` (has ``poses``) or a ``.smpl`` file
    (:mod:`smplcore.export.smplfile`) as a :class:`~smplcore.motion.Motion`, or a parameter set (``.npz`` or
    ``.json`` whose keys are model keyword arguments -- ``betas``, ``global_orient``, ``body_pose``, ``transl``,
    ... -- and optionally ``fps``) as a dict of arrays. No pickles are read.

    ``fps`` is the frame rate of a motion that states none (see :func:`_motion_input`); a motion
    without a frame rate and without ``fps`` is refused."""
    from smplcore.io import numeric_array, read_json, read_npz
    from smplcore.motion import load_motion

    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise FileNotFoundError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".json":
        raw = read_json(path, "a parameter set or motion (.json)")
        if not isinstance(raw, dict):
            raise ValueError(f"{path}: expected a JSON object of parameter arrays")
        if "poses" in raw:
            try:
                return _motion_input(raw, str(path), fps=fps)
            except ModelFileError:
                raise
            except (TypeError, ValueError) as exc:  # text or ragged lists where numbers are expected
                raise ModelFileError(path, f"expected arrays of numbers ({exc})") from None
        try:
            return {
                k: np.asarray(v, dtype=np.float64) if k not in ("gender", "model_type") else v for k, v in raw.items()
            }
        except (TypeError, ValueError) as exc:
            raise ModelFileError(path, f"expected arrays of numbers ({exc})") from None
    if suffix == ".smpl":
        from smplcore.export.smplfile import read_smpl

        return read_smpl(path).to_motion(default_fps=fps or 30.0)
    if suffix == ".npz":
        data = read_npz(path, "a parameter set or motion (.npz)")
        keys = set(data)
        if "poses" not in keys:
            return {k: (_text(data[k]) if _is_text(data[k]) else numeric_array(path, data[k], k)) for k in keys}
        _require_frame_rate(keys, path, fps)
        return load_motion(path, default_fps=fps)
    raise ValueError(
        f"{path}: unsupported input {path.suffix!r}; expected an AMASS-style .npz motion, a .smpl file or a "
        "parameter set (.npz or .json)"
    )


def fit_result_params(source: Any) -> Any:
    """A fit result (:class:`smplcore.fit.FitResult`, anything with a ``params`` dict of forward keywords) as a
    dict of NumPy arrays, one row per fitted body = per frame; any other ``source`` as it is."""
    params = getattr(source, "params", None)
    if isinstance(source, Mapping) or not isinstance(params, Mapping):
        return source
    out: dict[str, Any] = {}
    for key, value in params.items():
        if value is None:
            continue
        if hasattr(value, "detach"):  # a torch tensor
            value = value.detach().cpu().numpy()
        out[key] = np.asarray(value, dtype=np.float64)
    return out


def _require_frame_rate(keys: Any, source: str | Path, fps: float | None) -> None:
    """The export's wording of the motion reader's rule: no frame rate in the motion and none given
    is an error (a guessed rate would silently change the animation's speed)."""
    from smplcore.motion.sequence import FPS_KEYS

    if fps is None and not any(k in keys for k in FPS_KEYS):
        raise ModelFileError(
            source,
            "the motion states no frame rate (mocap_framerate or mocap_frame_rate); add it, or give "
            "it: fps=... (smplcore export --fps ...)",
            key="mocap_framerate",
        )


def _motion_input(arrays: Mapping[str, Any], source: str | Path = "<memory>", *, fps: float | None = None) -> Any:
    """AMASS-style arrays (``poses``, ``trans``, ``betas``, ``gender``, a frame rate, ...) as a
    :class:`~smplcore.motion.Motion`, read by the motion package's one reader
    (:func:`smplcore.motion.motion_from_arrays`).

    Frame rate: the one stated in ``arrays`` (``mocap_framerate``, ``mocap_frame_rate``, ``fps`` or
    ``frame_rate``), else ``fps``; neither is a :class:`~smplcore.errors.ModelFileError` -- never a
    guessed 30 fps. (:func:`prepare_animation` then lets ``fps`` override a stated rate.) For
    arrays from Python, a single frame of ``poses`` may be (3 J,) and ``trans`` may be left out (zeros).
    """
    from smplcore.motion import motion_from_arrays

    raw = dict(arrays)
    poses = np.asarray(raw["poses"], dtype=np.float64)
    raw["poses"] = poses[None] if poses.ndim == 1 else poses
    raw.setdefault("trans", np.zeros((raw["poses"].shape[0], 3)))
    _require_frame_rate(raw, source, fps)
    return motion_from_arrays(raw, source, default_fps=fps)


def _notify(notes: list[str], message: str) -> None:
    notes.append(message)
    warn(message)


def _fit_width(name: str, value: np.ndarray, width: int, notes: list[str]) -> np.ndarray:
    """Coefficients (..., n) to ``width`` by the one coefficient rule (:mod:`smplcore.model.params`)."""
    from smplcore.model.params import fit_width

    return fit_width(name, value, width, notes=notes)


def _single_shape(name: str, value: Any, width: int, notes: list[str]) -> np.ndarray:
    """One coefficient vector from (S,), (1, S) or (T, S) with identical rows."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None]
    if arr.ndim != 2:
        raise ShapeError(f"{name}: expected shape (S,) or (1, S), got {arr.shape}")
    if arr.shape[0] > 1 and not np.allclose(arr, arr[:1], rtol=0, atol=1e-9):
        raise ShapeError(
            f"{name}: a rigged export has one body shape, but the {arr.shape[0]} rows of {name} "
            "differ; export one shape at a time"
        )
    return _fit_width(name, arr[0], width, notes)


def _frames_of(params: Mapping[str, np.ndarray]) -> int:
    sizes = {k: v.shape[0] for k, v in params.items() if v.ndim > 1}
    frames = max(sizes.values(), default=1)
    for k, n in sizes.items():
        if n not in (1, frames):
            raise ShapeError(
                f"{k}: {n} frames do not match the {frames} frames of the other parameters "
                f"(sizes: {sizes}); give 1 or {frames}"
            )
    return frames
