"""A torch module's arrays for :func:`smplcore.frontend.evaluate`: smplx's buffers are the truth.

The modules register the same buffers as smplx (``v_template``, ``shapedirs``, ``expr_dirs``,
``posedirs``, ``J_regressor``, ``lbs_weights``, ``parents``, hand PCA, landmarks), so ``state_dict``
and in-place edits behave as there. The fast kernels' arrangement of them (:class:`BodyArrays`: one
coordinate-major blend basis, a joint basis, transposed weights) is derived from the buffers and
rebuilt whenever one of them changes: moved (``.to``), replaced, or edited in place (its version).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from smplcore.engine import body as engine
from smplcore.engine.kernels import ops
from smplcore.frontend.evaluate import PlainArrays

# Buffers the engine's arrays are derived from (expr_dirs only where the model has one).
SOURCE_BUFFERS = (
    "v_template",
    "shapedirs",
    "expr_dirs",
    "dmpldirs",
    "posedirs",
    "J_regressor",
    "lbs_weights",
    "parents",
)


def _blend_dirs(m: torch.nn.Module) -> torch.Tensor:
    """(V, 3, K) shape, expression and DMPL blend shapes (the module's buffers that it has), concatenated."""
    parts = [getattr(m, n) for n in ("shapedirs", "expr_dirs", "dmpldirs") if getattr(m, n, None) is not None]
    return parts[0] if len(parts) == 1 else torch.cat(parts, -1)


def _host(t: torch.Tensor) -> np.ndarray:
    return t.detach().to("cpu", torch.float64).numpy()


class ModuleArrays:
    """The :class:`~smplcore.frontend.evaluate.ArraySource` of a torch body module."""

    def __init__(self, module: torch.nn.Module) -> None:
        self.module: Any = module  # a body module: its buffers (v_template, ...) are duck-typed here
        self._key: tuple | None = None
        self._fast: engine.BodyArrays | None = None
        self.handle = ops.register(self)  # names these arrays in the custom operators (torch.compile)

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "handle"}

    def __setstate__(self, state: dict) -> None:  # a copy (copy.deepcopy, pickle) gets its own handle
        self.__dict__.update(state)
        self.handle = ops.register(self)

    def current(self) -> engine.BodyArrays:
        return self.fast_arrays()

    def last(self) -> engine.BodyArrays:
        return self._fast if self._fast is not None else self.fast_arrays()

    def latest_arrays(self) -> engine.BodyArrays:
        """The arrays as last built, without checking the buffers (what does not change with an edit:
        the tree, which bases exist, the shapes)."""
        return self.last()

    def _sources(self) -> list[torch.Tensor]:
        return [getattr(self.module, n) for n in SOURCE_BUFFERS if getattr(self.module, n, None) is not None]

    def fast_arrays(self) -> engine.BodyArrays:
        """The engine's arrays, rebuilt when a source buffer moved or was edited."""
        sources = self._sources()
        key = tuple((t.data_ptr(), t._version, t.dtype, t.device, tuple(t.shape)) for t in sources)
        if key != self._key or self._fast is None:
            self._fast, self._key = self._build(), key
        return self._fast

    def _build(self) -> engine.BodyArrays:
        m = self.module
        # one template per body (B, V, 3): the bases hold the first (a call with B > 1 runs the reference kernel)
        ref = m.v_template if m.v_template.ndim == 2 else m.v_template[0]
        dirs = _blend_dirs(m)
        num_verts = ref.shape[0]
        # a float32/float64 CPU buffer as it is (no float64 copy): the basis only copies it (same values)
        pose = m.posedirs.detach().cpu()
        pose = pose.numpy() if pose.dtype in (torch.float32, torch.float64) else _host(pose)
        posedirs = pose.reshape(-1, num_verts, 3).transpose(1, 2, 0)

        def convert(a: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.ascontiguousarray(a), dtype=ref.dtype, device=ref.device)

        with torch.inference_mode(False), torch.no_grad():
            return engine.BodyArrays.build(
                _host(ref),
                _host(dirs),
                _host(m.J_regressor),
                posedirs,
                _host(m.lbs_weights),
                m.parents.detach().cpu().numpy(),
                convert=convert,
            )

    def plain_arrays(self) -> PlainArrays:
        m = self.module
        dirs = _blend_dirs(m)
        return PlainArrays(m.v_template, dirs, m.posedirs, m.J_regressor, m.parent_list, m.lbs_weights)

    def constant(self, name: str, like: Any) -> Any:
        m = self.module
        if name == "zero":
            return m.v_template.new_zeros(1, 1)
        if name.startswith("hand_components/"):
            return getattr(m, m.hand_buffer(name.split("/", 1)[1], "components"))
        if name == "pose_mean":
            return m.pose_mean
        if name == "extra_ids":
            return m.vertex_joint_selector.extra_joints_idxs
        if name == "lmk_corners":
            return m.faces_tensor[m.lmk_faces_idx]
        if name == "lmk_bary":
            return m.lmk_bary_coords
        if name == "contour_corners":
            return m.faces_tensor[m.dynamic_lmk_faces_idx]
        if name == "contour_bary":
            return m.dynamic_lmk_bary_coords
        if name in ("regressor_ids", "regressor_weights"):
            return getattr(m, f"_{name}")
        raise KeyError(f"no model constant named {name!r}")

    def trainable(self) -> bool:
        return any(t.requires_grad for t in self._sources())
