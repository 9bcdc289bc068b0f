"""Model facts for :mod:`smplcore.join`, read in one place.

Until the public model contract (``model.rig``, :class:`smplcore.model.Rig`) is on this branch, the facts are
read here from the front end and returned under the contract's field names; switching is this one function.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PoseBlock:
    """A run of consecutive joints set by one keyword (the contract's ``PoseBlock``)."""

    name: str
    first_joint: int
    num_joints: int
    width: int
    pca: bool


@dataclass(frozen=True)
class RigFacts:
    """The subset of the contract's ``Rig`` that joining reads (same names, float64 NumPy arrays)."""

    model_type: str
    gender: str
    template: np.ndarray
    faces: np.ndarray
    shapedirs: np.ndarray
    exprdirs: np.ndarray
    joint_regressor: np.ndarray
    template_joints: np.ndarray
    joint_shapedirs: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    joint_names: tuple[str, ...]
    pose_blocks: tuple[PoseBlock, ...]
    hand_components: dict[str, np.ndarray]
    hand_means: dict[str, np.ndarray]
    num_betas: int
    num_expression_coeffs: int

    def block(self, name: str) -> PoseBlock:
        for candidate in self.pose_blocks:
            if candidate.name == name:
                return candidate
        raise KeyError(name)


_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _rig_of(model: Any) -> RigFacts:
    """The model facts of ``model`` (a :class:`smplcore.BodyModel` or a torch module of :func:`smplcore.create`)."""
    try:
        cached = _CACHE.get(model)
    except TypeError:
        cached = None
    if cached is not None:
        return cached
    facts = _read_facts(model)
    try:
        _CACHE[model] = facts
    except TypeError:
        pass
    return facts


def _read_facts(model: Any) -> RigFacts:
    setup = getattr(model, "setup", None)
    if setup is None:
        raise TypeError(
            f"model: expected a smplcore model (BodyModel or smplcore.create(...)), got {type(model).__name__}"
        )
    data, spec = setup.data, setup.spec
    blocks, start = [], 0
    for block in spec.pose_blocks:
        blocks.append(
            PoseBlock(block.name, start, block.num_joints, setup.pose_width(block.name), block.name in setup.pca_blocks)
        )
        start += block.num_joints
    template = np.asarray(data.v_template, dtype=np.float64)
    regressor = np.asarray(data.J_regressor, dtype=np.float64)
    shapedirs = np.asarray(setup.shapedirs, dtype=np.float64)
    names = tuple(spec.joint_names if data.joint_names is None else data.joint_names)
    return RigFacts(
        model_type=spec.model_type,
        gender=data.gender,
        template=template,
        faces=np.asarray(data.faces, dtype=np.int64),
        shapedirs=shapedirs,
        exprdirs=np.asarray(setup.exprdirs, dtype=np.float64),
        joint_regressor=regressor,
        template_joints=regressor @ template,
        joint_shapedirs=(regressor @ shapedirs.reshape(len(template), -1)).reshape(len(regressor), 3, -1),
        weights=np.asarray(data.weights, dtype=np.float64),
        parents=np.asarray(data.parents, dtype=np.int64),
        joint_names=names,
        pose_blocks=tuple(blocks),
        hand_components={k: np.asarray(v, dtype=np.float64) for k, v in setup.hand_components.items()},
        hand_means={k: np.asarray(v, dtype=np.float64) for k, v in setup.hand_means.items()},
        num_betas=int(setup.num_betas),
        num_expression_coeffs=int(setup.num_expression_coeffs),
    )
