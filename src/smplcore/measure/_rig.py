"""The one place :mod:`smplcore.measure` reads model facts (switches to the public ``model.rig``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class _Facts:
    """The fields of :class:`smplcore.model.Rig` this package reads (same names and meanings)."""

    model_type: str
    gender: str
    num_vertices: int
    num_betas: int
    template: np.ndarray
    faces: np.ndarray
    shapedirs: np.ndarray
    joint_regressor: np.ndarray
    joint_names: tuple[str, ...]


def _rig_of(model: Any) -> Any:
    """Model facts of a front end (``BodyModel`` or a torch module): ``model.rig`` when the front end has
    the public contract, else the same fields gathered once from the front end."""
    rig = getattr(model, "rig", None)
    if rig is not None:
        return rig
    setup = getattr(model, "setup", None)
    if setup is None:
        raise TypeError(f"model: expected a smplcore body model (BodyModel or smplcore.create(...)), got {type(model)}")
    data = setup.data
    template = np.asarray(data.v_template, dtype=np.float64)
    reg = data.J_regressor
    reg = np.asarray(reg.toarray() if hasattr(reg, "toarray") else reg, dtype=np.float64)
    return _Facts(
        model_type=setup.spec.model_type,
        gender=str(data.gender),
        num_vertices=int(template.shape[0]),
        num_betas=int(setup.shapedirs.shape[2]),
        template=template,
        faces=np.asarray(data.faces, dtype=np.int64),
        shapedirs=np.asarray(setup.shapedirs, dtype=np.float64),
        joint_regressor=reg,
        joint_names=tuple(str(n) for n in (setup.spec.joint_names if data.joint_names is None else data.joint_names)),
    )
