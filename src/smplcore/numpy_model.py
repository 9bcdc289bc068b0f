"""The NumPy front end: every model of the family with NumPy in and out, no torch needed."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.engine.kernels.select import check_kernel
from smplcore.frontend import SETUP_OPTIONS, ModelSetup, SetupArrays, evaluate, warn_once
from smplcore.frontend.inputs import rows
from smplcore.frontend.setup import hand_options_from_file
from smplcore.io.locate import read_model
from smplcore.io.model_data import ModelData
from smplcore.model.rig import Rig, rig_of


@dataclass
class BodyOutput:
    """Result of :meth:`BodyModel.__call__` (NumPy arrays, batch first).

    ``vertices`` (B, V, 3) (None with ``return_verts=False``), ``joints`` (B, J', 3) with extra joints
    and landmarks, ``full_pose`` (B, 3 J) axis-angle or (B, J, 3, 3) with rotation matrices,
    ``rotmats`` (B, J, 3, 3), ``betas``, ``expression``, ``transl`` and the pose blocks as used.
    """

    vertices: np.ndarray | None
    joints: np.ndarray
    full_pose: np.ndarray
    rotmats: np.ndarray
    betas: np.ndarray
    expression: np.ndarray | None = None
    transl: np.ndarray | None = None
    pose: dict[str, np.ndarray] | None = None


class BodyModel:
    """A body model of the SMPL family evaluated with NumPy.

    Parameters
    ----------
    model_path : model file or folder (as for :func:`smplcore.create`); None with
        ``model_type="open"`` for the packaged open model.
    model_type : ``smpl``, ``smplh``, ``smplx``, ``mano``, ``flame`` or ``open``; taken from the file
        when a file is given.
    gender, ext, num_betas, num_expression_coeffs, use_pca, num_pca_comps, flat_hand_mean,
    use_face_contour, use_hands, use_feet_keypoints, age, kid_template_path, is_rhand :
        as in smplx.
    dtype : float32 (default) or float64.
    kernel : ``"auto"`` (default), ``"blocked"`` or ``"reference"`` (the plain forward of
        :mod:`smplcore.engine.reference`); see :mod:`smplcore.engine.kernels`.
    check_finite : refuse NaN / inf inputs with an error naming the argument (default True).
    check_rotations : with ``pose2rot=False``, refuse matrices that are not rotations (default True).
    skinning : ``"lbs"`` (default: linear blend skinning, what the models were built for) or ``"dqs"``
        (dual-quaternion skinning: no candy-wrapper collapse under twists); see docs/skinning.md.
    uv_path : a UV map ``.obj`` for the model's mesh (as SMPL distributes it); files that carry ``vt``/``ft``
        (SMPL-X, the open model) need none.
    dmpl_path : a DMPL file (``dmpl.npz`` with ``eigvec`` (V, 3, n), as AMASS ships it) for any model of
        the same vertex count; the forward then takes ``dmpls`` (B, n), added to the shaped template.

    Examples
    --------
    >>> model = BodyModel(model_type="open")
    >>> out = model(betas=np.zeros((2, 10)), body_pose=np.zeros((2, 69)))
    >>> out.vertices.shape[0], out.joints.shape[1]
    (2, 45)
    """

    def __init__(
        self,
        model_path: str | Path | None = None,
        model_type: str | None = None,
        *,
        gender: str = "neutral",
        ext: str | None = None,
        dtype: Any = np.float32,
        is_rhand: bool = True,
        data: ModelData | None = None,
        kernel: str = "auto",
        check_finite: bool = True,
        check_rotations: bool = True,
        uv_path: str | Path | None = None,
        **options: Any,
    ) -> None:
        if data is None:
            data = read_model(model_path, model_type, gender=gender, ext=ext, is_rhand=is_rhand)
        if uv_path is not None:  # SMPL distributes its UV map as a separate .obj
            from smplcore.io.uv import attach_uv

            data = attach_uv(data, uv_path)
        known = set(SETUP_OPTIONS)
        for name in sorted(set(options) - known):
            warn_once("BodyModel", f"BodyModel: ignoring unknown keyword argument {name!r}", key=name)
        try:
            self.dtype = np.dtype(dtype)
        except TypeError as exc:
            raise TypeError(f"dtype: expected float32 or float64, got {dtype!r}") from exc
        if self.dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype: expected float32 or float64, got {self.dtype}")
        given = {k: v for k, v in options.items() if k in known}
        given.update(hand_options_from_file(data, given))  # AMASS's .npz: no hand PCA, no mean hand pose
        self.setup = ModelSetup.build(data, owner="BodyModel", **given)
        self.kernel = check_kernel(kernel)
        self.skinning = self.setup.skinning
        self.check_finite, self.check_rotations = bool(check_finite), bool(check_rotations)
        self.source = SetupArrays(self.setup, lambda a: np.ascontiguousarray(a, dtype=self.dtype))
        self.faces = np.asarray(data.faces)

    @property
    def rig(self) -> Rig:
        """The model's public facts with its options applied (:class:`smplcore.model.Rig`), built on first use."""
        return rig_of(self.setup)

    @property
    def model_data(self) -> ModelData:
        """The file's arrays the model was built from (:class:`smplcore.io.ModelData`, options not applied)."""
        return self.setup.data

    @property
    def arrays(self) -> Any:
        """The engine's arrays (:class:`smplcore.engine.BodyArrays`) in this model's dtype."""
        return self.source.fast_arrays()

    @property
    def uv(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(vt, ft)``: (T, 2) UV coordinates and (F, 3) UV faces, or None when the model has no UV map."""
        d = self.setup.data
        return (d.vt, d.ft) if d.vt is not None and d.ft is not None else None  # d.has_uv

    @property
    def model_type(self) -> str:
        return self.setup.spec.model_type

    @property
    def gender(self) -> str:
        """The model's gender, normalised: ``"neutral"``, ``"male"``, ``"female"`` (MANO: ``"right"`` /
        ``"left"``), as the file says (else as asked for)."""
        return self.setup.data.gender

    @property
    def num_betas(self) -> int:
        return self.setup.num_betas

    @property
    def num_expression_coeffs(self) -> int:
        return self.setup.num_expression_coeffs

    @property
    def num_dmpls(self) -> int:
        """DMPL coefficients ``dmpls`` takes (0 without ``dmpl_path``)."""
        return self.setup.num_dmpls

    @property
    def joint_names(self) -> list[str]:
        """Names of ``output.joints``, in order."""
        return self.setup.output_joint_names

    @property
    def skeleton_joint_names(self) -> list[str]:
        """Names of the J skeleton joints (without extra joints and landmarks)."""
        return self.setup.output_joint_names[: self.setup.data.num_joints]

    @property
    def parents(self) -> np.ndarray:
        """(J,) parent of each skeleton joint, -1 for the root."""
        return np.asarray(self.setup.data.parents)

    @property
    def skinning_weights(self) -> np.ndarray:
        """(V, J) linear-blend-skinning weights."""
        return np.asarray(self.setup.data.weights)

    @property
    def has_pose_correctives(self) -> bool:
        """Whether the model has (non-zero) pose-corrective blend shapes."""
        return self.arrays.has_pose_correctives

    def rest_pose(self, betas: Any = None, expression: Any = None, dmpls: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """The shaped body before posing: vertices (V, 3) and skeleton joints (J, 3) for one body.

        ``betas`` / ``expression`` / ``dmpls`` are 1-D (or (1, n)); narrower than the model's count is
        zero-padded.
        """
        from smplcore.engine import body as engine

        coeffs = []
        for name, value, width in (
            ("betas", betas, self.num_betas),
            ("expression", expression, self.num_expression_coeffs),
            ("dmpls", dmpls, self.num_dmpls),
        ):
            if (name == "expression" and not self.setup.spec.has_expression) or (name == "dmpls" and not width):
                continue
            value = np.zeros((1, width), self.dtype) if value is None else np.asarray(value, self.dtype)
            coeffs.append(rows(name, value, 1, width, allow_narrower=True))
        c = np.concatenate(coeffs, axis=1)
        return engine.shaped_vertices(c, self.arrays)[0], engine.rest_joints(c, self.arrays)[0]

    @property
    def pose_blocks(self) -> list[str]:
        """Keyword names of the pose blocks this model takes."""
        return [block.name for block in self.setup.spec.pose_blocks]

    def __call__(self, *, pose2rot: bool = True, return_verts: bool = True, **params: Any) -> BodyOutput:
        """Pose the model.

        Keyword arguments are ``betas``, ``expression``, ``transl``, the pose blocks
        (:attr:`pose_blocks`) and, for a model created with ``dmpl_path``, ``dmpls`` (B, n), as NumPy
        arrays (or anything ``np.asarray`` takes); batch 1 broadcasts. With ``pose2rot=False`` pose
        blocks are rotation matrices (B, n, 3, 3).
        """
        allowed = set(self.pose_blocks) | {"betas", "expression", "transl", "dmpls"}
        for name in sorted(set(params) - allowed):
            warn_once("BodyModel.__call__", f"BodyModel: ignoring unknown keyword argument {name!r}", key=name)
        arrays = {k: None if v is None else _as_array(k, v, self.dtype) for k, v in params.items() if k in allowed}
        out = evaluate(
            self.setup,
            self.source,
            arrays,
            rotation_matrices=not pose2rot,
            vertices=return_verts,
            like=np.zeros((1, 1), self.dtype),
            kernel=self.kernel,
            check_finite=self.check_finite,
            check_rotations=self.check_rotations,
        )
        return BodyOutput(
            vertices=out.vertices,
            joints=out.joints,
            full_pose=out.full_pose,
            rotmats=out.rotmats,
            betas=out.betas,
            expression=out.expression,
            transl=out.transl,
            pose=dict(out.pose),
        )


def _as_array(name: str, value: Any, dtype: np.dtype) -> np.ndarray:
    """``value`` as a NumPy array of ``dtype``, or a TypeError naming the argument and the fix."""
    if hasattr(value, "requires_grad") and getattr(value, "requires_grad", False):
        raise TypeError(
            f"{name}: a torch tensor that requires grad; BodyModel is NumPy only: pass "
            f"{name}.detach().cpu().numpy(), or use smplcore.create(...) for gradients"
        )
    if getattr(value, "is_sparse", False) or type(value).__module__.startswith("scipy.sparse"):
        raise TypeError(f"{name}: sparse arrays are not accepted; pass a dense array")
    try:
        return np.asarray(value, dtype=dtype)
    except (TypeError, ValueError, RuntimeError) as exc:
        raise TypeError(f"{name}: expected an array of numbers ({exc})") from None
