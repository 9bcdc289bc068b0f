"""PyTorch modules with smplx's public API (``create``, ``SMPL``, ``SMPLLayer``, ...) over smplcore's engine.

One module class, :class:`BodyModule`, serves every model; the public classes only name their
family spec, their forward's positional order and their output class. Constructor and forward
keywords, buffers, parameters and outputs follow smplx 0.1.28; where smplx misbehaves (see the
README's "Differences from smplx") we do the right thing instead.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from smplcore.engine import body as engine
from smplcore.errors import ShapeError
from smplcore.family.specs import FLAME as FLAME_SPEC
from smplcore.family.specs import MANO as MANO_SPEC
from smplcore.family.specs import OPEN as OPEN_SPEC
from smplcore.family.specs import SMPL as SMPL_SPEC
from smplcore.family.specs import SMPLH as SMPLH_SPEC
from smplcore.family.specs import SMPLX as SMPLX_SPEC
from smplcore.family.specs import FamilySpec, get_spec
from smplcore.io.locate import read_model
from smplcore.io.model_data import ModelData
from smplcore.io.model_files import _from_official
from smplcore.model_setup import ModelSetup, batch_of, evaluate, warn_once
from smplcore.torch.outputs import Deferred, FLAMEOutput, MANOOutput, ModelOutput, SMPLHOutput, SMPLOutput, SMPLXOutput

__all__ = [
    "create",
    "build_layer",
    "BodyModule",
    "SMPL",
    "SMPLH",
    "SMPLX",
    "MANO",
    "FLAME",
    "OpenModel",
    "SMPLLayer",
    "SMPLHLayer",
    "SMPLXLayer",
    "MANOLayer",
    "FLAMELayer",
    "ModelOutput",
    "SMPLOutput",
    "SMPLHOutput",
    "SMPLXOutput",
    "MANOOutput",
    "FLAMEOutput",
]

# smplx's constructor keywords that set up the model (all other known ones create parameters).
_SETUP_OPTIONS = {
    "num_betas": 10,
    "num_expression_coeffs": 10,
    "use_pca": True,
    "num_pca_comps": 6,
    "flat_hand_mean": False,
    "use_face_contour": False,
    "use_hands": True,
    "use_feet_keypoints": True,
    "vertex_ids": None,
    "age": "adult",
    "kid_template_path": "",
    "v_template": None,
}
# Accepted for compatibility and without effect here.
_INERT_OPTIONS = {"use_compressed", "create_vertex_joint_selector"}

_ENGINE_FIELDS = ("blend_basis", "joint_basis", "weights_t")


def _block_flag(block_name: str) -> str:
    """smplx's ``create_*`` flag for a pose block (``body_pose`` → ``create_body_pose``)."""
    return f"create_{block_name}"


class BodyModule(nn.Module):
    """A body model of the SMPL family as a torch module (the engine behind every public class)."""

    SPEC: FamilySpec = SMPL_SPEC
    LAYER = False
    FORWARD_ARGS: tuple[str, ...] = (
        "betas",
        "body_pose",
        "global_orient",
        "transl",
        "return_verts",
        "return_full_pose",
        "pose2rot",
    )
    OUTPUT: type = SMPLOutput
    MAPPER_TAKES_VERTICES = False
    SHAPE_SPACE_DIM = 300

    def __init__(
        self,
        model_path: str | Path | None = None,
        *,
        data_struct: Any = None,
        data: ModelData | None = None,
        gender: str = "neutral",
        ext: str = "pkl",
        dtype: torch.dtype = torch.float32,
        batch_size: int = 1,
        joint_mapper: Callable | None = None,
        is_rhand: bool = True,
        **kwargs: Any,
    ) -> None:
        super().__init__()
        spec = self.SPEC
        name = type(self).__name__
        setup_opts = {k: kwargs.pop(k) for k in list(kwargs) if k in _SETUP_OPTIONS}
        block_names = [b.name for b in spec.pose_blocks]
        param_names = block_names + ["betas", "transl"] + (["expression"] if spec.has_expression else [])
        initial = {k: kwargs.pop(k) for k in list(kwargs) if k in param_names}
        create = {k: bool(kwargs.pop(_block_flag(k), True)) for k in param_names}
        for k in list(kwargs):
            if k in _INERT_OPTIONS or (k.startswith("create_") and k[7:] in _any_block_names()):
                kwargs.pop(k)
        for k in sorted(kwargs):
            warn_once(name, f"{name}: ignoring unknown keyword argument {k!r}", key=k)

        if data is None and data_struct is not None:
            data = _from_official(Path(f"<data_struct for {name}>"), dict(vars(data_struct)), spec.model_type, gender)
        if data is None:
            data = read_model(model_path, spec.model_type, gender=gender, ext=ext, is_rhand=is_rhand)
        if data.model_type != spec.model_type:
            raise ValueError(
                f"{name} cannot run a {data.model_type!r} model from {data.source}; "
                f"use smplcore.create() to pick the class from the file"
            )
        if self.LAYER:
            setup_opts["use_pca"] = False
        setup = ModelSetup.build(data, owner=name, **setup_opts)
        self.setup = setup
        self.dtype = dtype
        self.gender = data.gender
        self.age = setup_opts.get("age", "adult")
        self.is_rhand = data.gender != "left"
        self.batch_size = batch_size
        self.joint_mapper = joint_mapper
        self.use_pca = setup.use_pca
        self.num_pca_comps = setup.num_pca_comps
        self.flat_hand_mean = setup.flat_hand_mean
        self.use_face_contour = setup.use_face_contour
        self._register_buffers(setup, dtype)
        if not self.LAYER:
            self._create_parameters(setup, initial, create, batch_size, dtype)

    # -- construction -------------------------------------------------------------------------------

    def _register_buffers(self, setup: ModelSetup, dtype: torch.dtype) -> None:
        d = setup.data

        def as_float(a: np.ndarray) -> torch.Tensor:
            return torch.tensor(np.asarray(a), dtype=dtype)

        self.faces = np.asarray(d.faces)
        self.register_buffer("faces_tensor", torch.tensor(self.faces, dtype=torch.long))
        self.register_buffer("v_template", as_float(d.v_template))
        self.register_buffer("J_regressor", as_float(d.J_regressor))
        self.register_buffer("lbs_weights", as_float(d.weights))
        self.register_buffer("parents", torch.tensor(d.parents, dtype=torch.long))
        for block, comps in setup.hand_components.items():
            self.register_buffer(self._hand_buffer(block, "components"), as_float(comps))
        for block, mean in setup.hand_means.items():
            self.register_buffer(self._hand_buffer(block, "mean"), as_float(mean))
        if setup.hand_means:
            self.register_buffer("pose_mean", as_float(setup.pose_mean))
        if self.SPEC.landmarks:
            self.register_buffer("lmk_faces_idx", torch.tensor(d.lmk_faces_idx, dtype=torch.long))
            self.register_buffer("lmk_bary_coords", as_float(d.lmk_bary_coords))
            if setup.use_face_contour:
                self.register_buffer("dynamic_lmk_faces_idx", torch.tensor(d.dynamic_lmk_faces_idx, dtype=torch.long))
                self.register_buffer("dynamic_lmk_bary_coords", as_float(d.dynamic_lmk_bary_coords))
                self.register_buffer("neck_kin_chain", torch.as_tensor(setup.neck_chain, dtype=torch.long))
        arrays = setup.body_arrays(as_float)
        self._tree, self._num_coeffs = arrays.tree, arrays.num_coeffs
        self._engine_derived: dict = {}  # BodyArrays.derived: vertex blocks and keypoint subsets, kept across calls
        for field in _ENGINE_FIELDS:
            value = getattr(arrays, field)
            self.register_buffer(f"_engine_{field}", value, persistent=False)

    @staticmethod
    def _hand_buffer(block: str, kind: str) -> str:
        """smplx's buffer names: ``left_hand_components``, ``right_hand_mean``, ``hand_mean``, ..."""
        return block.replace("_pose", "") + "_" + kind

    def _create_parameters(
        self, setup: ModelSetup, initial: dict, create: dict, batch_size: int, dtype: torch.dtype
    ) -> None:
        widths = {b.name: setup.pose_width(b.name) for b in self.SPEC.pose_blocks}
        widths.update(betas=setup.num_betas, transl=3)
        if self.SPEC.has_expression:
            widths["expression"] = setup.num_expression_coeffs
        for name, width in widths.items():
            if not create[name]:
                continue
            value = initial.get(name)
            if value is None:
                tensor = torch.zeros(batch_size, width, dtype=dtype)
            else:
                tensor = torch.as_tensor(value, dtype=dtype).detach().clone()
                if tensor.ndim == 1:
                    tensor = tensor[None]
            self.register_parameter(name, nn.Parameter(tensor, requires_grad=True))

    # -- smplx's accessors --------------------------------------------------------------------------

    @property
    def num_betas(self) -> int:
        return self.setup.num_betas

    @property
    def num_expression_coeffs(self) -> int:
        return self.setup.num_expression_coeffs

    @property
    def joint_names(self) -> list[str]:
        """Names of ``output.joints`` (before any ``joint_mapper``), in order."""
        return self.setup.output_joint_names

    def name(self) -> str:
        return self.SPEC.display_name

    def get_num_verts(self) -> int:
        return int(self.v_template.shape[0])

    def get_num_faces(self) -> int:
        return int(self.faces.shape[0])

    def extra_repr(self) -> str:
        lines = [
            f"Gender: {self.gender.upper()}",
            f"Number of joints: {self.J_regressor.shape[0]}",
            f"Betas: {self.num_betas}",
        ]
        if self.SPEC.has_expression:
            lines.append(f"Number of expression coefficients: {self.num_expression_coeffs}")
        if self.SPEC.hand_blocks:
            if self.use_pca:
                lines.append(f"Number of PCA components: {self.num_pca_comps}")
            lines.append(f"Flat hand mean: {self.flat_hand_mean}")
        return "\n".join(lines)

    @torch.no_grad()
    def reset_params(self, **params_dict: Any) -> None:
        for param_name, param in self.named_parameters():
            if param_name in params_dict:
                param[:] = torch.as_tensor(params_dict[param_name])
            else:
                param.fill_(0)

    def _engine_arrays(self) -> engine.BodyArrays:
        return engine.BodyArrays(
            self._engine_blend_basis,
            self._num_coeffs,
            self._engine_joint_basis,
            self._engine_weights_t,
            self._tree,
            self._engine_derived,
        )

    # smplx's blend-shape buffers, as views of the engine's single basis (no second copy in memory)
    def _basis_rows(self, start: int, stop: int) -> torch.Tensor:
        """(n, V, 3) view of rows ``start:stop`` of the engine's coordinate-major basis."""
        rows = self._engine_blend_basis[start:stop]
        return rows.reshape(rows.shape[0], 3, -1).transpose(1, 2)

    @property
    def shapedirs(self) -> torch.Tensor:
        """(V, 3, num_betas) shape blend shapes (a view of the engine's basis)."""
        return self._basis_rows(1, 1 + self.num_betas).permute(1, 2, 0)

    @property
    def expr_dirs(self) -> torch.Tensor:
        """(V, 3, num_expression_coeffs) expression blend shapes (SMPL-X, FLAME; a view)."""
        return self._basis_rows(1 + self.num_betas, 1 + self._num_coeffs).permute(1, 2, 0)

    @property
    def posedirs(self) -> torch.Tensor:
        """(P, V * 3) pose correctives, as smplx stores them (zeros for a model without any)."""
        start = 1 + self._num_coeffs
        if self._engine_blend_basis.shape[0] > start:
            return self._basis_rows(start, None).reshape(-1, self.get_num_verts() * 3)
        return self.v_template.new_zeros(9 * (self.J_regressor.shape[0] - 1), self.get_num_verts() * 3)

    def forward_shape(self, betas: torch.Tensor | None = None) -> ModelOutput:
        """The shaped template (no pose): ``vertices == v_shaped``, (B, V, 3)."""
        betas = self._as_tensor("betas", betas if betas is not None else getattr(self, "betas", None))
        if betas is None:
            betas = self.v_template.new_zeros(1, self.num_betas)
        v_shaped = self._v_shaped(betas)
        return self.OUTPUT(vertices=v_shaped, betas=betas, v_shaped=v_shaped)

    def _v_shaped(self, betas: torch.Tensor) -> torch.Tensor:
        """(B, V, 3) template + shape blend of ``betas`` (no expression, no pose), one GEMM."""
        if betas.ndim == 1:
            betas = betas[None]
        if betas.shape[-1] > self.num_betas:
            raise ShapeError(f"betas: expected shape (B, <={self.num_betas}), got {tuple(betas.shape)}")
        ones = torch.ones_like(betas[:, :1])
        rows = self._engine_blend_basis[: 1 + betas.shape[-1]]
        flat = torch.cat([ones, betas], dim=1) @ rows
        return flat.reshape(betas.shape[0], 3, -1).transpose(1, 2).contiguous()

    # -- forward -----------------------------------------------------------------------------------

    def _as_tensor(self, name: str, value: Any) -> torch.Tensor | None:
        if value is None:
            return None
        ref = self.v_template
        if isinstance(value, torch.Tensor) and value.dtype == ref.dtype and value.device == ref.device:
            return value
        try:
            return torch.as_tensor(value, dtype=ref.dtype, device=ref.device)
        except (TypeError, ValueError, RuntimeError) as exc:
            raise TypeError(f"{name}: expected a tensor or array of numbers ({exc})") from None

    def forward(self, *args: Any, **kwargs: Any) -> ModelOutput:
        """Pose the model; the keywords (and positional order) are smplx's for this class.

        Pose blocks left out use the module's parameters (none for Layer classes: zero rotation);
        a parameter of batch 1 broadcasts to the batch of the others. Unknown keywords are ignored
        with a warning that names them.
        """
        if len(args) > len(self.FORWARD_ARGS):
            raise TypeError(
                f"{type(self).__name__}.forward takes at most {len(self.FORWARD_ARGS)} positional "
                f"arguments ({', '.join(self.FORWARD_ARGS)})"
            )
        for key, value in zip(self.FORWARD_ARGS, args):
            if key in kwargs:
                raise TypeError(f"{type(self).__name__}.forward got multiple values for argument {key!r}")
            kwargs[key] = value
        return_verts = bool(kwargs.pop("return_verts", True))
        return_full_pose = bool(kwargs.pop("return_full_pose", False))
        pose2rot = bool(kwargs.pop("pose2rot", True)) and not self.LAYER
        return_shaped = bool(kwargs.pop("return_shaped", True))
        names = [b.name for b in self.SPEC.pose_blocks] + ["betas", "transl"]
        names += ["expression"] if self.SPEC.has_expression else []
        for key in sorted(set(kwargs) - set(names)):
            warn_once(
                f"{type(self).__name__}.forward",
                f"{type(self).__name__}.forward: ignoring unknown keyword argument {key!r}",
                key=key,
            )
        given = {k: self._as_tensor(k, kwargs.get(k)) for k in names}
        params = self._with_defaults(given, use_pose_defaults=pose2rot)
        out = evaluate(
            self.setup,
            self._engine_arrays(),
            params,
            rotation_matrices=not pose2rot,
            vertices=return_verts,
            like=self.v_template,
        )
        vertices, joints = out["vertices"], out["joints"]
        if self.joint_mapper is not None:
            joints = (
                self.joint_mapper(joints=joints, vertices=vertices)
                if self.MAPPER_TAKES_VERTICES
                else self.joint_mapper(joints)
            )
        transl = out["transl"]
        if transl is not None:  # the engine translated the vertices already
            joints = joints + transl[:, None]
        fields = {
            "vertices": vertices,
            "joints": joints,
            "betas": params.get("betas", out["betas"]),
            "transl": transl,
            "full_pose": out["full_pose"] if return_full_pose else None,
        }
        for block in self.SPEC.pose_blocks:
            fields[block.name] = out[block.name]
        if self.SPEC.has_expression:
            fields["expression"] = out["expression"]
        if self.SPEC.model_type == "smplx" and return_shaped and return_verts:
            betas = out["betas"][:, : self.num_betas].clone()  # a later in-place edit must not change it
            fields["v_shaped"] = Deferred(self._in_current_grad_mode(lambda: self._v_shaped(betas)))
        known = {f for f in self.OUTPUT.__dataclass_fields__}
        return self.OUTPUT(**{k: v for k, v in fields.items() if k in known})

    @staticmethod
    def _in_current_grad_mode(fn: Callable[[], torch.Tensor]) -> Callable[[], torch.Tensor]:
        """``fn`` to be run later (a deferred output) under the grad / inference mode of now."""
        grad, inference = torch.is_grad_enabled(), torch.is_inference_mode_enabled()

        def run() -> torch.Tensor:
            with torch.inference_mode(inference), torch.set_grad_enabled(grad):
                return fn()

        return run

    def _with_defaults(self, given: dict[str, torch.Tensor | None], use_pose_defaults: bool) -> dict:
        """Fill what the call left out from the module's parameters, without the batch-size trap.

        A parameter created with ``batch_size=b`` joins a call of another batch size when all its
        rows are equal (e.g. untouched zeros); otherwise the mismatch is an error naming it.
        """
        explicit = {k: v for k, v in given.items() if v is not None}
        batch = batch_of(
            {
                k: (v if v.ndim > 1 else v[None])
                for k, v in explicit.items()
                if not (k in {b.name for b in self.SPEC.pose_blocks} and not use_pose_defaults)
            }
        )
        params = dict(given)
        for key, value in given.items():
            if value is not None:
                continue
            is_pose = key not in ("betas", "transl", "expression")
            default = getattr(self, key, None) if (use_pose_defaults or not is_pose) else None
            if not isinstance(default, torch.Tensor):
                continue
            if default.shape[0] not in (1, batch) and explicit:
                if bool(torch.all(default == default[:1])):
                    default = default[:1]
                else:
                    raise ShapeError(
                        f"{key}: the module's parameter has batch size {default.shape[0]} "
                        f"(batch_size at construction), but this call has batch size {batch}; "
                        f"pass {key} explicitly"
                    )
            params[key] = default
        return params


def _any_block_names() -> set[str]:
    from smplcore.family.specs import SPECS

    names = {"betas", "transl", "expression"}
    for spec in SPECS.values():
        names.update(b.name for b in spec.pose_blocks)
    return names


_SMPLH_ARGS = ("betas", "global_orient", "body_pose", "left_hand_pose", "right_hand_pose", "transl")
_TAIL = ("return_verts", "return_full_pose", "pose2rot")


class SMPL(BodyModule):
    """SMPL (24 joints; outputs 45 with the extra vertex joints)."""

    SPEC = SMPL_SPEC
    NUM_JOINTS = 23
    NUM_BODY_JOINTS = 23


class SMPLH(BodyModule):
    """SMPL+H: SMPL's body with articulated hands (52 joints; outputs 73)."""

    SPEC = SMPLH_SPEC
    FORWARD_ARGS = _SMPLH_ARGS + _TAIL
    OUTPUT = SMPLHOutput
    NUM_BODY_JOINTS = 21
    NUM_HAND_JOINTS = 15
    NUM_JOINTS = 51


class SMPLX(BodyModule):
    """SMPL-X: body, hands and face (55 joints; outputs 127, or 144 with the face contour)."""

    SPEC = SMPLX_SPEC
    FORWARD_ARGS = _SMPLH_ARGS + ("expression", "jaw_pose", "leye_pose", "reye_pose") + _TAIL + ("return_shaped",)
    OUTPUT = SMPLXOutput
    MAPPER_TAKES_VERTICES = True
    NUM_BODY_JOINTS = 21
    NUM_HAND_JOINTS = 15
    NUM_FACE_JOINTS = 3
    NUM_JOINTS = 54
    EXPRESSION_SPACE_DIM = 100
    NECK_IDX = 12


class MANO(BodyModule):
    """MANO hand (16 joints). ``is_rhand`` picks ``MANO_RIGHT``/``MANO_LEFT`` in a folder.

    ``fix_left_shapedirs=True`` (left hand only) flips the sign of the x-component of the shape
    blend shapes, the known error of the official left-hand file.
    """

    SPEC = MANO_SPEC
    FORWARD_ARGS = ("betas", "global_orient", "hand_pose", "transl", "return_verts", "return_full_pose")
    OUTPUT = MANOOutput
    NUM_BODY_JOINTS = 1
    NUM_HAND_JOINTS = 15
    NUM_JOINTS = 16

    def __init__(self, model_path: str | Path | None = None, *, fix_left_shapedirs: bool = False, **kwargs: Any):
        super().__init__(model_path, **kwargs)
        if fix_left_shapedirs and not self.is_rhand:
            self.fix_left_shapedirs()

    @torch.no_grad()
    def fix_left_shapedirs(self) -> None:
        """Flip the x-component of the left hand's shape blend shapes (the official file's sign error)."""
        if self.is_rhand:
            raise ValueError("fix_left_shapedirs: only the left MANO hand has the sign error")
        data = self.setup.data
        fixed = np.array(data.shapedirs)
        fixed[:, 0, :] *= -1
        self.setup = ModelSetup.build(
            data.replace(shapedirs=fixed),
            owner="MANO",
            use_pca=self.use_pca,
            num_pca_comps=self.num_pca_comps,
            flat_hand_mean=self.flat_hand_mean,
            num_betas=self.num_betas,
        )
        arrays = self.setup.body_arrays(
            lambda a: torch.as_tensor(a, dtype=self.v_template.dtype, device=self.v_template.device)
        )
        for field in _ENGINE_FIELDS:
            getattr(self, f"_engine_{field}").copy_(getattr(arrays, field))


class FLAME(BodyModule):
    """FLAME head (5 joints; outputs 56, or 73 with the face contour)."""

    SPEC = FLAME_SPEC
    FORWARD_ARGS = (
        "betas",
        "global_orient",
        "neck_pose",
        "transl",
        "expression",
        "jaw_pose",
        "leye_pose",
        "reye_pose",
        "return_verts",
        "return_full_pose",
        "pose2rot",
    )
    OUTPUT = FLAMEOutput
    MAPPER_TAKES_VERTICES = True
    NUM_JOINTS = 5
    SHAPE_SPACE_DIM = 300
    EXPRESSION_SPACE_DIM = 100
    NECK_IDX = 0


class OpenModel(SMPL):
    """smplcore's open CC0 body model in the SMPL layout (24 joints; outputs 45). Loads with no files."""

    SPEC = OPEN_SPEC

    def __init__(self, model_path: str | Path | None = None, **kwargs: Any) -> None:
        super().__init__(model_path, **kwargs)

    def name(self) -> str:
        return "OPEN"


def _layer(cls: type, doc: str) -> type:
    return type(f"{cls.__name__}Layer", (cls,), {"LAYER": True, "__doc__": doc, "__module__": __name__})


SMPLLayer = _layer(SMPL, "SMPL taking rotation matrices (B, J, 3, 3) and holding no parameters.")
SMPLHLayer = _layer(SMPLH, "SMPL+H taking rotation matrices (B, J, 3, 3) and holding no parameters.")
SMPLXLayer = _layer(SMPLX, "SMPL-X taking rotation matrices (B, J, 3, 3) and holding no parameters.")
MANOLayer = _layer(MANO, "MANO taking rotation matrices (B, J, 3, 3) and holding no parameters.")
FLAMELayer = _layer(FLAME, "FLAME taking rotation matrices (B, J, 3, 3) and holding no parameters.")

_CLASSES = {
    "smpl": (SMPL, SMPLLayer),
    "smplh": (SMPLH, SMPLHLayer),
    "smplx": (SMPLX, SMPLXLayer),
    "mano": (MANO, MANOLayer),
    "flame": (FLAME, FLAMELayer),
    "open": (OpenModel, None),
}


def _resolve(model_path: str | Path | None, model_type: str | None, layer: bool, kwargs: dict) -> BodyModule:
    from smplcore.io.model_files import load_model

    path = None if model_path is None or str(model_path) == "" else Path(model_path)
    if path is not None and path.is_file():
        data = load_model(path, model_type=model_type)
        model_type = data.model_type
        kwargs["data"] = data
    elif model_type is None:
        model_type = "smpl" if path is not None else "open"
    key = get_spec(model_type).model_type
    cls = _CLASSES[key][1 if layer else 0]
    if cls is None:
        raise ValueError(f"model_type: there is no Layer class for {model_type!r}")
    return cls(model_path if "data" not in kwargs else None, **kwargs)


def create(model_path: str | Path | None = None, model_type: str | None = None, **kwargs: Any) -> BodyModule:
    """Build the module for a model file or folder, as ``smplx.create``.

    Parameters
    ----------
    model_path : a model file (its type is read from the file: official names such as
        ``basicModel_f_lbs_10_207_0_v1.0.0.pkl`` or ``generic_model.pkl`` work), or a folder laid out
        as smplx expects (``<folder>/<model_type>/SMPLX_NEUTRAL.npz``, or the files directly in it).
        None with ``model_type="open"`` loads the packaged open model.
    model_type : ``smpl`` (default for folders), ``smplh``, ``smplx``, ``mano``, ``flame`` or ``open``.
    **kwargs : the class's constructor keywords (``gender``, ``ext``, ``num_betas``, ``use_pca``, ...).
    """
    return _resolve(model_path, model_type, False, kwargs)


def build_layer(model_path: str | Path | None = None, model_type: str | None = None, **kwargs: Any) -> BodyModule:
    """Like :func:`create`, for the Layer classes (rotation-matrix inputs, no parameters)."""
    return _resolve(model_path, model_type, True, kwargs)
