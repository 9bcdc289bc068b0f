"""A posable body for the viewer and the video writer: a NumPy :class:`~smplcore.BodyModel`, its current
parameters (batch 1, edited in place by the GUI) and an optional motion track.

The NumPy model is used because at batch 1 it is the fastest front end on the CPU (about 3 ms per SMPL-X
forward against about 5 ms for torch on a 2-core EPYC). The keyword arrays handed to the model are views
into one (J, 3) full pose, so a slider move changes a number and re-evaluates, with nothing rebuilt.
"""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError, warn
from smplcore.view.sources import Source

MODEL_TYPES = ("open", "smpl", "smplh", "smplx", "mano", "flame")
GENDERS = ("neutral", "male", "female")


def build_model(
    model_path: str | Path | None = None,
    model_type: str | None = None,
    gender: str = "neutral",
    *,
    num_betas: int = 10,
    num_expression_coeffs: int = 10,
    flat_hand_mean: bool = False,
    age: float | None = None,
) -> Any:
    """A NumPy body model for viewing: the open model without ``model_path`` (at ``age`` years if given);
    hands as full axis-angle poses (no PCA), so every hand joint has its own rotation control."""
    from smplcore import BodyModel

    options: dict[str, Any] = {"num_betas": max(int(num_betas), 1), "flat_hand_mean": flat_hand_mean}
    if model_path is None and model_type in (None, "open"):
        if age is not None:
            options["age"] = float(age)
        return BodyModel(model_type="open", gender=gender, **options)  # it has three genders too
    if model_type not in (None, "open", "mano", "flame", "smpl"):
        options["use_pca"] = False
    if model_type in ("smplx", "flame", None):
        options["num_expression_coeffs"] = num_expression_coeffs
    with warnings.catch_warnings():
        # BodyModel warns about options a model type does not take; those are left out above where known.
        warnings.simplefilter("ignore")
        try:
            model = BodyModel(model_path, model_type=model_type, gender=gender, **options)
        except ModelFileError:
            if model_path is None or not Path(model_path).is_dir():
                raise
            try:  # a folder holding .npz files only: the gendered file under the other extension
                return BodyModel(model_path, model_type=model_type, gender=gender, ext="npz", **options)
            except ModelFileError:
                pass
            raise
    if model_type is None and model.model_type in ("smplh", "smplx"):
        # a model file on its own: its type is known only now; load it again with axis-angle hands (no PCA)
        return build_model(
            model_path,
            model.model_type,
            gender,
            num_betas=num_betas,
            num_expression_coeffs=num_expression_coeffs,
            flat_hand_mean=flat_hand_mean,
        )
    return model


def _fit(name: str, value: np.ndarray, width: int) -> np.ndarray:
    """(..., n) cut or zero-padded to (..., width)."""
    n = value.shape[-1]
    if n == width:
        return value
    if n > width:
        warn(f"{name}: the input has {n} coefficients, the model takes {width}; dropping the rest")
        return value[..., :width]
    pad = np.zeros((*value.shape[:-1], width - n), dtype=value.dtype)
    return np.concatenate([value, pad], axis=-1)


class Track:
    """A motion as per-frame arrays for one model.

    Attributes
    ----------
    poses : (T, J, 3) axis-angle per skeleton joint of the model.
    transl : (T, 3).
    betas : (S,) the model's ``num_betas``.
    expression : (T, E) or None.
    fps : frames per second.
    """

    def __init__(self, model: Any, source: Source) -> None:
        from smplcore.motion import Motion

        motion = source.bvh.to_motion(model) if source.bvh is not None else source.motion
        self.fps = float(source.fps or 30.0)
        if isinstance(motion, Motion):
            params = motion.model_params(model.model_type, model.skeleton_joint_names, model.num_betas)
        elif source.params is not None:
            params = {k: np.asarray(v, dtype=np.float64) for k, v in source.params.items() if not isinstance(v, str)}
        else:
            raise ValueError("Track: the source has no motion or parameters")
        offsets = _block_offsets(model)
        frames = max(
            (np.atleast_2d(params[b]).shape[0] for b in (*offsets, "transl", "expression") if b in params), default=1
        )
        num_joints = len(model.skeleton_joint_names)
        self.poses = np.zeros((frames, num_joints, 3))
        for block, (start, stop) in offsets.items():
            if block in params:
                value = np.atleast_2d(params[block])
                if value.shape[-1] != 3 * (stop - start):
                    raise ValueError(
                        f"{source.label}: {block} has {value.shape[-1]} values per frame, the {model.model_type} "
                        f"model takes {3 * (stop - start)} (PCA hand poses cannot be shown)"
                    )
                self.poses[:, start:stop] = value.reshape(value.shape[0], stop - start, 3)
        self.transl = np.broadcast_to(np.atleast_2d(params.get("transl", np.zeros(3))), (frames, 3)).copy()
        betas = np.atleast_2d(params.get("betas", np.zeros((1, model.num_betas))))[0]
        self.betas = _fit("betas", betas, model.num_betas)
        self.expression = None
        if model.num_expression_coeffs and "expression" in params:
            expr = np.atleast_2d(params["expression"])
            expr = _fit("expression", expr, model.num_expression_coeffs)
            self.expression = np.broadcast_to(expr, (frames, expr.shape[-1])).copy()

    @property
    def num_frames(self) -> int:
        return int(self.poses.shape[0])


_CONTROLLER: list[Any] = []


def _one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """Limit BLAS to one thread (threadpoolctl, in the ``view`` extra); no limit without threadpoolctl."""
    if not _CONTROLLER:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:
            _CONTROLLER.append(None)
        else:
            _CONTROLLER.append(ThreadpoolController())
    ctl = _CONTROLLER[0]
    return contextlib.nullcontext() if ctl is None else ctl.limit(limits=1, user_api="blas")


def _block_offsets(model: Any) -> dict[str, tuple[int, int]]:
    from smplcore.family.specs import get_spec

    return get_spec(model.model_type).block_offsets()


class Body:
    """One body: a model, its parameters for batch 1 and an optional :class:`Track`.

    Attributes
    ----------
    model : the :class:`smplcore.BodyModel`.
    full_pose : (J, 3) axis-angle per skeleton joint, edited in place.
    betas : (S,), expression : (E,) (empty for models without one), transl : (3,).
    track : the motion, or None; :meth:`set_frame` copies a frame into the parameters.
    """

    def __init__(self, model: Any, source: Source | None = None, label: str | None = None) -> None:
        self.source = source or Source()
        self.label = label or self.source.label
        self.model = model
        self.faces = np.ascontiguousarray(model.faces, dtype=np.uint32)
        dtype = model.dtype
        self.joint_names = list(model.skeleton_joint_names)
        self.full_pose = np.zeros((len(self.joint_names), 3), dtype)
        self.betas = np.zeros(model.num_betas, dtype)
        self.expression = np.zeros(model.num_expression_coeffs, dtype)
        self.transl = np.zeros(3, dtype)
        self.frame = 0
        # Keyword arrays for the model: views into the arrays above, shaped (1, n).
        self._kwargs: dict[str, np.ndarray] = {
            block: self.full_pose[start:stop].reshape(1, -1) for block, (start, stop) in _block_offsets(model).items()
        }
        self._kwargs["betas"] = self.betas.reshape(1, -1)
        self._kwargs["transl"] = self.transl.reshape(1, -1)
        if self.expression.size:
            self._kwargs["expression"] = self.expression.reshape(1, -1)
        self.track: Track | None = None
        if self.source.motion is not None or self.source.bvh is not None or self.source.params is not None:
            self.track = Track(model, self.source)
            self.betas[:] = self.track.betas
            self.set_frame(0)

    @property
    def num_frames(self) -> int:
        return 1 if self.track is None else self.track.num_frames

    def set_frame(self, frame: int) -> None:
        """Copy frame ``frame`` (clipped to the track) of the track into the pose, translation and expression."""
        if self.track is None:
            return
        k = int(np.clip(frame, 0, self.track.num_frames - 1))
        self.frame = k
        self.full_pose[:] = self.track.poses[k]
        self.transl[:] = self.track.transl[k]
        if self.track.expression is not None:
            self.expression[:] = self.track.expression[k]

    def evaluate(self) -> tuple[np.ndarray, np.ndarray]:
        """The posed mesh: vertices (V, 3) float32 and skeleton joints (J, 3).

        BLAS runs on one thread here: at batch 1 the products are small, and on a busy CPU (a browser, other
        work) two OpenBLAS threads waiting for each other made a SMPL-X update 4x slower (60 vs 15 ms)."""
        with _one_blas_thread():
            out = self.model(**self._kwargs)
        return out.vertices[0], out.joints[0, : len(self.joint_names)]

    def params(self) -> dict[str, np.ndarray]:
        """The current parameters as model keyword arrays (copies), e.g. for :func:`smplcore.export.save_glb`."""
        return {k: v.copy() for k, v in self._kwargs.items()}

    def evaluate_frames(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Frames ``start:stop`` of the track in one batch: vertices (n, V, 3) and skeleton joints (n, J, 3)
        (the current parameters repeated when there is no track)."""
        if self.track is None:
            verts, joints = self.evaluate()
            n = stop - start
            return np.repeat(verts[None], n, 0), np.repeat(joints[None], n, 0)
        t = self.track
        sl = slice(start, stop)
        n = len(range(*sl.indices(t.num_frames)))
        kwargs: dict[str, np.ndarray] = {
            block: t.poses[sl, a:b].reshape(n, -1) for block, (a, b) in _block_offsets(self.model).items()
        }
        kwargs["transl"] = t.transl[sl]
        kwargs["betas"] = self.betas[None]
        if t.expression is not None:
            kwargs["expression"] = t.expression[sl]
        elif self.expression.size:
            kwargs["expression"] = self.expression[None]
        out = self.model(**kwargs)
        return out.vertices, out.joints[:, : len(self.joint_names)]
