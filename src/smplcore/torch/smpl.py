"""The implementation behind every torch model class: :class:`SMPL` (smplx's root class) reads the model,
registers smplx's buffers and parameters, and runs the forward through :func:`smplcore.frontend.evaluate`.
The subclasses in :mod:`smplcore.torch.models` only state data."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from smplcore.engine import reference
from smplcore.engine.kernels.select import check_kernel, traced
from smplcore.errors import ShapeError
from smplcore.family.specs import SMPL as SMPL_SPEC
from smplcore.family.specs import FamilySpec
from smplcore.frontend import SETUP_OPTIONS, ModelSetup, evaluate
from smplcore.frontend.setup import hand_options_from_file
from smplcore.io.model_data import ModelData
from smplcore.model.rig import Rig, rig_of
from smplcore.torch.arrays import ModuleArrays
from smplcore.torch.buffers import hand_buffer, numpy_hand_components, register_buffers
from smplcore.torch.keywords import split_keywords, warn_unknown
from smplcore.torch.loading import has_hand_pca, load_data, per_body_templates
from smplcore.torch.outputs import (
    Deferred,
    ModelOutput,
    SMPLOutput,
    lazy,
)
from smplcore.torch.selector import VertexJointSelector
from smplcore.torch.signature import is_ours, mark, with_signature

__all__ = ["SMPL", "VertexJointSelector"]


class SMPL(nn.Module):
    """SMPL (24 joints; outputs 45 with the extra vertex joints), and the implementation of every class."""

    SPEC: FamilySpec = SMPL_SPEC
    # registered buffers, declared for the type checker (nn.Module.__getattr__ types them Tensor | Module)
    faces_tensor: torch.Tensor
    shapedirs: torch.Tensor
    v_template: torch.Tensor
    J_regressor: torch.Tensor
    posedirs: torch.Tensor
    parents: torch.Tensor
    lbs_weights: torch.Tensor
    LAYER = False
    NUM_JOINTS = 23
    NUM_BODY_JOINTS = 23
    SHAPE_SPACE_DIM = 300
    DEFAULT_EXT = "pkl"
    FORWARD_ARGS: tuple[str, ...] = (
        "betas",
        "body_pose",
        "global_orient",
        "transl",
        "return_verts",
        "return_full_pose",
        "pose2rot",
    )
    OUTPUT: type[Any] = SMPLOutput
    MAPPER_TAKES_VERTICES = False
    #: smplx's parameters, in the order it creates them; the Layer class creates only LAYER_PARAMETERS.
    PARAMETERS: tuple[str, ...] = ("betas", "global_orient", "body_pose", "transl")
    LAYER_PARAMETERS: tuple[str, ...] = ()

    def __init__(
        self,
        model_path: str | Path | None = None,
        *,
        data_struct: Any = None,
        data: ModelData | None = None,
        gender: str = "neutral",
        ext: str | None = None,
        dtype: torch.dtype = torch.float32,
        batch_size: int = 1,
        joint_mapper: Callable | None = None,
        is_rhand: bool = True,
        kernel: str = "auto",
        check_finite: bool = True,
        check_rotations: bool = False,
        uv_path: str | Path | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__()
        spec, name = self.SPEC, type(self).__name__
        setup_opts, initial, create = split_keywords(name, kwargs, self.PARAMETERS)
        # smplx takes every option in every class and ignores those that do not apply: so do we
        if not spec.landmarks:
            setup_opts.pop("use_face_contour", None)
        if not spec.hand_blocks:
            for option in ("use_pca", "num_pca_comps", "flat_hand_mean"):
                setup_opts.pop(option, None)
        data = load_data(type(self), model_path, data_struct, data, gender, ext or self.DEFAULT_EXT, is_rhand)
        if uv_path is not None:  # SMPL distributes its UV map as a separate .obj
            from smplcore.io.uv import attach_uv

            data = attach_uv(data, uv_path)
        templates = per_body_templates(setup_opts, data)  # (B, V, 3) v_template: one per body, as smplx keeps it
        if self.LAYER and "use_pca" not in setup_opts and not has_hand_pca(data):
            setup_opts["use_pca"] = False  # a Layer never reads PCA hands; smplx still registers the bases
        setup_opts.update(hand_options_from_file(data, setup_opts))  # AMASS's .npz: no hand PCA, no mean
        self.setup = setup = ModelSetup.build(data, owner=name, **setup_opts)
        self.kernel = check_kernel(kernel)
        self.skinning = setup.skinning  # "lbs" or "dqs" (the skinning option)
        self.check_finite, self.check_rotations = bool(check_finite), bool(check_rotations)
        self.dtype = dtype
        self.gender = data.gender if spec.model_type == "open" else gender  # the open model's: normalised
        self.age = setup_opts.get("age", SETUP_OPTIONS["age"])
        self.batch_size = batch_size
        self.joint_mapper = joint_mapper
        if spec.hand_blocks:
            self.use_pca, self.num_pca_comps, self.flat_hand_mean = (
                setup.use_pca,
                setup.num_pca_comps,
                setup.flat_hand_mean,
            )
            comps = int(setup_opts.get("num_pca_comps", SETUP_OPTIONS["num_pca_comps"]))
            for attribute, value in numpy_hand_components(self.SPEC, data, comps).items():
                setattr(self, attribute, value)
        if spec.landmarks:
            self.use_face_contour = setup.use_face_contour
        self.faces = np.asarray(data.faces).astype(data.faces_dtype)
        self.parent_list = tuple(int(p) for p in data.parents)
        register_buffers(self, setup, dtype, templates, use_hands=setup_opts.get("use_hands", True))
        self.source = ModuleArrays(self)
        self.source.fast_arrays()  # built now, as the buffers are (not in the first forward's time and memory)
        for param in self.PARAMETERS:
            if create[param] and (not self.LAYER or param in self.LAYER_PARAMETERS):
                self._create_parameter(param, initial.get(param), batch_size, dtype)

    # -- construction -------------------------------------------------------------------------------

    hand_buffer = staticmethod(hand_buffer)

    def _parameter_width(self, name: str) -> int:
        if name == "betas":
            return self.setup.num_betas
        if name == "expression":
            return self.setup.num_expression_coeffs
        if name == "transl":
            return 3
        if name == "body_pose" and name not in {b.name for b in self.SPEC.pose_blocks}:
            return 3 * self.NUM_BODY_JOINTS  # smplx creates it for MANO and FLAME too, unused
        return self.setup.pose_width(name)

    def _create_parameter(self, name: str, value: Any, batch_size: int, dtype: torch.dtype) -> None:
        if value is None:
            tensor = torch.zeros(batch_size, self._parameter_width(name), dtype=dtype)
        else:
            tensor = torch.as_tensor(value, dtype=dtype).detach().clone()
            if tensor.ndim == 1:
                tensor = tensor[None]
        self.register_parameter(name, nn.Parameter(tensor, requires_grad=True))

    @property
    def rig(self) -> Rig:
        """The model's public facts with its options applied (:class:`smplcore.model.Rig`), built on first use."""
        if self.v_template.ndim == 3 and self.v_template.shape[0] > 1:
            raise ValueError(
                f"rig: this model holds {self.v_template.shape[0]} templates (v_template of shape "
                f"{tuple(self.v_template.shape)}, one per body) and a Rig describes one body; make a model with one "
                "of them (smplcore.create(..., v_template=templates[i])) for fitting, export or measuring"
            )
        return rig_of(self.setup)

    @property
    def model_data(self) -> ModelData:
        """The file's arrays the model was built from (:class:`smplcore.io.ModelData`, options not applied)."""
        return self.setup.data

    # -- smplx's accessors --------------------------------------------------------------------------

    @property
    def num_betas(self) -> int:
        return self.setup.num_betas

    @property
    def _num_betas(self) -> int:  # smplx's private name, read by some of its clients
        return self.setup.num_betas

    @property
    def _num_expression_coeffs(self) -> int:  # smplx's private name (SMPL-X and FLAME only)
        if not self.SPEC.has_expression:
            raise AttributeError(f"{type(self).__name__} has no expression coefficients")
        return self.setup.num_expression_coeffs

    @property
    def num_expression_coeffs(self) -> int:
        return self.setup.num_expression_coeffs

    @property
    def num_dmpls(self) -> int:
        """DMPL coefficients the forward's ``dmpls`` takes (0 without ``dmpl_path``)."""
        return self.setup.num_dmpls

    @property
    def joint_names(self) -> list[str]:
        """Names of ``output.joints`` (before any ``joint_mapper``), in order."""
        return self.setup.output_joint_names

    def name(self) -> str:
        return self.SPEC.display_name

    def get_num_verts(self) -> int:
        """Vertices of the mesh (smplx answers the batch size for a per-body (B, V, 3) ``v_template``)."""
        return int(self.v_template.shape[-2])

    def get_num_faces(self) -> int:
        return int(self.faces.shape[0])

    def extra_repr(self) -> str:
        """smplx's lines: gender, joints, betas; then hand PCA, expression and face contour as its class has them."""
        lines = [
            f"Gender: {str(self.gender).upper()}",
            f"Number of joints: {self.J_regressor.shape[0]}",
            f"Betas: {self.num_betas}",
        ]
        if self.SPEC.hand_blocks:
            if self.use_pca:
                lines.append(f"Number of PCA components: {self.num_pca_comps}")
            lines.append(f"Flat hand mean: {self.flat_hand_mean}")
        if self.SPEC.has_expression:
            lines.append(f"Number of Expression Coefficients: {self.num_expression_coeffs}")
            if not self.SPEC.hand_blocks:  # FLAME
                lines.append(f"Use face contour: {self.use_face_contour}")
        return "\n".join(lines)

    def create_mean_pose(self, data_struct: Any = None, flat_hand_mean: bool = False) -> Any:
        """The mean pose added to the full pose, as smplx returns it (``data_struct`` and ``flat_hand_mean``
        are ignored, as in smplx: the hand means chosen at construction are used): None for models
        without hands, a tensor for SMPL+H and MANO, a NumPy array for SMPL-X."""
        if not self.SPEC.hand_blocks:
            return None
        mean = torch.as_tensor(self.setup.pose_mean, dtype=self.dtype)
        return mean.numpy() if self.SPEC.model_type == "smplx" else mean

    @torch.no_grad()
    def reset_params(self, **params_dict: Any) -> None:
        for param_name, param in self.named_parameters():
            if param_name in params_dict:
                param[:] = torch.as_tensor(params_dict[param_name])
            else:
                param.fill_(0)

    def forward_shape(self, betas: torch.Tensor | None = None) -> ModelOutput:
        """The shaped template (no pose): ``vertices == v_shaped``, (B, V, 3)."""
        betas = self._as_tensor("betas", betas if betas is not None else getattr(self, "betas", None))
        if betas is None:
            betas = self.v_template.new_zeros(1, self.num_betas)
        v_shaped = self._v_shaped(betas)
        return self.OUTPUT(vertices=v_shaped, betas=betas, v_shaped=v_shaped)

    def _v_shaped(self, betas: torch.Tensor) -> torch.Tensor:
        """(B, V, 3) template + shape blend of ``betas`` (no expression, no pose), from the buffers."""
        if betas.ndim == 1:
            betas = betas[None]
        if betas.shape[-1] > self.num_betas:
            raise ShapeError(
                f"betas: expected shape (B, <={self.num_betas}), got {tuple(betas.shape)}; the model was made with "
                f"num_betas={self.num_betas}: make it with num_betas={betas.shape[-1]} (e.g. "
                f"smplcore.create(..., num_betas={betas.shape[-1]})) if its file holds that many"
            )
        return reference.shape_blend(self.v_template, self.shapedirs[:, :, : betas.shape[-1]], betas)

    # -- forward -----------------------------------------------------------------------------------

    def _as_tensor(self, name: str, value: Any) -> torch.Tensor | None:
        if value is None:
            return None
        ref = self.v_template
        if isinstance(value, torch.Tensor) and value.layout != torch.strided:
            raise TypeError(f"{name}: sparse tensors are not accepted; pass {name}.to_dense()")
        if isinstance(value, torch.Tensor) and value.dtype == ref.dtype and value.device == ref.device:
            return value
        try:
            return torch.as_tensor(value, dtype=ref.dtype, device=ref.device)
        except (TypeError, ValueError, RuntimeError) as exc:
            raise TypeError(f"{name}: expected a tensor or array of numbers ({exc})") from None

    def forward(self, *args: Any, **kwargs: Any) -> ModelOutput:
        """Pose the model; the parameters (and their positional order) are smplx's for this class, as
        ``inspect.signature(model.forward)`` lists them.

        Pose blocks left out use the module's parameters (none for Layer classes: zero rotation);
        a parameter of batch 1 broadcasts to the batch of the others; batch 0 gives empty outputs.
        smplcore's keywords: ``kernel=`` forces a kernel for this call (see :mod:`smplcore.engine.kernels`),
        ``check_finite=False`` skips the NaN / inf check of the inputs (on by default, CPU only),
        ``check_rotations=True`` checks that rotation-matrix inputs are rotations (None: the model's
        settings); ``dmpls`` (B, n) DMPL coefficients (models made with ``dmpl_path``); ``v_template`` a rest
        template for this call, (V, 3) or (B, V, 3) one per body (runs the reference kernel).
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
        kernel = kwargs.pop("kernel", None)
        kernel = self.kernel if kernel is None else kernel
        finite, rotations = kwargs.pop("check_finite", None), kwargs.pop("check_rotations", None)
        finite = self.check_finite if finite is None else bool(finite)
        rotations = self.check_rotations if rotations is None else bool(rotations)
        template = self._call_template(kwargs.pop("v_template", None))
        names = [b.name for b in self.SPEC.pose_blocks] + ["betas", "transl"]
        names += ["expression"] if self.SPEC.has_expression else []
        names += ["dmpls"]  # (B, n) DMPL coefficients; an error without dmpl_path
        warn_unknown(f"{type(self).__name__}.forward", set(kwargs) - set(names), forward=True)
        given = {k: self._as_tensor(k, kwargs.get(k)) for k in names}
        params = self._with_defaults(given, use_pose_defaults=pose2rot)
        out = evaluate(
            self.setup,
            self.source,
            params,
            rotation_matrices=not pose2rot,
            vertices=return_verts,
            like=self.v_template,
            kernel=kernel,
            check_finite=finite,
            check_rotations=rotations,
            template=template,
        )
        vertices, joints = out.vertices, out.untranslated_joints
        if self.joint_mapper is not None:
            joints = (
                self.joint_mapper(joints=joints, vertices=vertices)
                if self.MAPPER_TAKES_VERTICES
                else self.joint_mapper(joints)
            )
        if out.transl is not None:  # the evaluation translated the vertices already
            joints = joints + out.transl[:, None]
        betas = params.get("betas")
        fields = {
            "vertices": vertices,
            "joints": joints,
            "betas": out.betas if betas is None else betas,
            "full_pose": out.full_pose if return_full_pose else None,
            **out.pose,
        }
        if self.SPEC.has_expression:
            fields["expression"] = out.expression
        if self.OUTPUT_TRANSL:  # smplx fills it for SMPLXLayer only
            fields["transl"] = (
                out.transl if out.transl is not None else self.v_template.new_zeros(out.betas.shape[0], 3)
            )
        if self.SPEC.model_type == "smplx" and not self.LAYER and return_shaped and return_verts:
            shape = out.betas[:, : self.num_betas]
            if traced():
                fields["v_shaped"] = self._v_shaped(shape)
            else:
                shape = shape.clone()  # a later in-place edit must not change it
                fields["v_shaped"] = Deferred(self._in_current_grad_mode(lambda: self._v_shaped(shape)))
        known = self.OUTPUT.__dataclass_fields__
        output = self.OUTPUT if not any(type(v) is Deferred for v in fields.values()) else lazy(self.OUTPUT)
        return output(**{k: v for k, v in fields.items() if k in known})

    OUTPUT_TRANSL = False

    def _call_template(self, value: Any) -> torch.Tensor | None:
        """The template a call runs on, for :func:`evaluate`: ``value`` given to the forward ((V, 3) or
        (B, V, 3), checked), else the module's own when it holds one per body, else None (the model's)."""
        if value is None:
            own = self.v_template
            return own if own.ndim == 3 and own.shape[0] > 1 else None
        template = self._as_tensor("v_template", value)
        assert template is not None
        num_verts = self.get_num_verts()
        if template.ndim not in (2, 3) or tuple(template.shape[-2:]) != (num_verts, 3) or 0 in template.shape:
            raise ShapeError(
                f"v_template: expected shape ({num_verts}, 3) or (B, {num_verts}, 3) (one template per body), "
                f"got {tuple(template.shape)}"
            )
        return template

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Each class's ``forward`` shows smplx's parameters of that class (``inspect.signature``); a subclass
        that defines its own forward (as SPIN's does) keeps it."""
        super().__init_subclass__(**kwargs)
        if "forward" not in cls.__dict__ and is_ours(cls.forward):
            cls.forward = with_signature(cls, SMPL.forward)  # type: ignore[method-assign]

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
        pose_names = {b.name for b in self.SPEC.pose_blocks}
        batch = 1
        for key, value in given.items():
            if value is not None and value.ndim > 1 and (use_pose_defaults or key not in pose_names):
                batch = max(batch, value.shape[0])
        explicit = any(v is not None for v in given.values())
        params = dict(given)
        for key, value in given.items():
            if value is not None or (key in pose_names and not use_pose_defaults):
                continue
            default = getattr(self, key, None)
            if not isinstance(default, torch.Tensor):
                continue
            if default.shape[0] not in (1, batch) and explicit:
                if traced() or bool(torch.all(default == default[:1])):
                    default = default[:1]
                else:
                    raise ShapeError(
                        f"{key}: the module's parameter has batch size {default.shape[0]} "
                        f"(batch_size at construction), but this call has batch size {batch}; "
                        f"pass {key} explicitly"
                    )
            params[key] = default
        return params


mark(SMPL, SMPL.forward)
