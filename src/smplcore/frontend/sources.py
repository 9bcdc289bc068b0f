"""An :class:`~smplcore.frontend.evaluate.ArraySource` over a :class:`ModelSetup`'s NumPy arrays, converted
once to the namespace, dtype and device that ``convert`` gives (the NumPy ``BodyModel``, the motion pipeline)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from smplcore.engine import body as engine
from smplcore.frontend.evaluate import PlainArrays
from smplcore.frontend.setup import ModelSetup


def constant_array(setup: ModelSetup, name: str) -> np.ndarray:
    """The NumPy array behind a constant name of :meth:`ArraySource.constant`."""
    kp, d = setup.keypoints, setup.data
    if name == "zero":
        return np.zeros((1, 1))
    if name.startswith("hand_components/"):
        return setup.hand_components[name.split("/", 1)[1]]
    table = {
        "pose_mean": lambda: setup.pose_mean,
        "extra_ids": lambda: kp.extra,
        "lmk_corners": lambda: kp.corners,
        "lmk_bary": lambda: d.lmk_bary_coords,
        "contour_corners": lambda: kp.contour_corners,
        "contour_bary": lambda: d.dynamic_lmk_bary_coords,
        "regressor_ids": lambda: setup.regressor.vertex_ids,
        "regressor_weights": lambda: setup.regressor.weights,
    }
    if name not in table:
        raise KeyError(f"no model constant named {name!r}")
    return table[name]()


def plain_arrays(setup: ModelSetup, convert: Callable[[np.ndarray], Any]) -> PlainArrays:
    """The setup's arrays in the official layout (shape, expression and DMPL columns together)."""
    d = setup.data
    dirs = setup.blend_dirs()
    posedirs = None
    if d.posedirs is not None and np.any(d.posedirs):
        posedirs = convert(np.asarray(d.posedirs).reshape(-1, d.posedirs.shape[-1]).T)
    return PlainArrays(
        convert(d.v_template),
        convert(dirs),
        posedirs,
        convert(d.J_regressor),
        tuple(int(p) for p in d.parents),
        convert(d.weights),
    )


class SetupArrays:
    """Arrays of ``setup`` through ``convert`` (e.g. to float32 NumPy, or to torch tensors), built on first use."""

    def __init__(self, setup: ModelSetup, convert: Callable[[np.ndarray], Any]) -> None:
        self.setup, self.convert = setup, convert
        self._fast: engine.BodyArrays | None = None
        self._plain: PlainArrays | None = None
        self._constants: dict[str, Any] = {}

    handle = None  # not known to the custom operators (never compiled)

    def latest_arrays(self) -> engine.BodyArrays:
        return self.fast_arrays()

    def fast_arrays(self) -> engine.BodyArrays:
        if self._fast is None:
            self._fast = self.setup.body_arrays(self.convert)
        return self._fast

    def plain_arrays(self) -> PlainArrays:
        if self._plain is None:
            self._plain = plain_arrays(self.setup, self.convert)
        return self._plain

    def constant(self, name: str, like: Any) -> Any:
        if name not in self._constants:
            array = np.asarray(constant_array(self.setup, name))
            self._constants[name] = np.asarray(array, np.int64) if array.dtype.kind in "iu" else self.convert(array)
            if array.dtype.kind in "iu" and not isinstance(self.convert(np.zeros(1)), np.ndarray):
                import torch

                self._constants[name] = torch.as_tensor(self._constants[name])
        return self._constants[name]

    def trainable(self) -> bool:
        return False
