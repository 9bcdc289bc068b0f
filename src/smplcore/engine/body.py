"""The body-model forward pass, once for every model and both namespaces.

:class:`BodyArrays` holds a model's arrays arranged for fast evaluation (bases as matrices, shape
terms of the joints precomputed); :func:`forward` maps shape coefficients and joint rotations to
posed vertices and joints:

    shape blend → joint regression → pose correctives → kinematic chain → skinning
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from smplcore.engine.rotations import pose_features
from smplcore.engine.skeleton import KinematicTree, skin, skinning_transforms, world_transforms


@dataclass
class BodyArrays:
    """A model's arrays in one namespace, dtype and device.

    Attributes
    ----------
    v_template : (V, 3).
    shape_basis : (K, V * 3) shape (and expression) blend shapes, one row per coefficient.
    joint_template : (J, 3) rest joints of the template, ``J_regressor @ v_template``.
    joint_shape_basis : (K, J * 3) how each coefficient moves the rest joints.
    pose_basis : (P, V * 3) pose correctives, or None.
    weights : (V, J) skinning weights.
    tree : the kinematic tree.
    """

    v_template: Any
    shape_basis: Any
    joint_template: Any
    joint_shape_basis: Any
    pose_basis: Any | None
    weights: Any
    tree: KinematicTree

    @classmethod
    def build(cls, v_template: np.ndarray, shapedirs: np.ndarray, J_regressor: np.ndarray,
              posedirs: np.ndarray | None, weights: np.ndarray, parents: np.ndarray,
              convert: Callable[[np.ndarray], Any] = np.asarray) -> "BodyArrays":
        """Arrange NumPy model arrays for evaluation; ``convert`` moves each to the target namespace.

        ``shapedirs`` is (V, 3, K) (shape and expression columns already concatenated), ``posedirs``
        (V, 3, P) or None when the model has no (or only zero) pose correctives.
        """
        v_template = np.asarray(v_template, dtype=np.float64)
        shapedirs = np.asarray(shapedirs, dtype=np.float64)
        J_regressor = np.asarray(J_regressor, dtype=np.float64)
        num_verts, num_coeffs = v_template.shape[0], shapedirs.shape[-1]
        joint_shape = np.einsum("jv,vdk->kjd", J_regressor, shapedirs).reshape(num_coeffs, -1)
        pose_basis = None
        if posedirs is not None and np.any(posedirs):
            pose_basis = convert(np.asarray(posedirs).reshape(num_verts * 3, -1).T)
        return cls(
            v_template=convert(v_template),
            shape_basis=convert(shapedirs.reshape(num_verts * 3, num_coeffs).T),
            joint_template=convert(J_regressor @ v_template),
            joint_shape_basis=convert(joint_shape),
            pose_basis=pose_basis,
            weights=convert(np.asarray(weights)),
            tree=KinematicTree.from_parents(parents),
        )

    def map(self, fn: Callable[[Any], Any]) -> "BodyArrays":
        """The same arrays with ``fn`` applied to each (e.g. a dtype or device change)."""
        return BodyArrays(
            fn(self.v_template), fn(self.shape_basis), fn(self.joint_template), fn(self.joint_shape_basis),
            None if self.pose_basis is None else fn(self.pose_basis), fn(self.weights), self.tree)


def shaped_vertices(coeffs: Any, arrays: BodyArrays) -> Any:
    """(B, V, 3) rest-pose vertices for (B, K) shape coefficients."""
    batch = coeffs.shape[0]
    return arrays.v_template + (coeffs @ arrays.shape_basis).reshape(batch, -1, 3)


def rest_joints(coeffs: Any, arrays: BodyArrays) -> Any:
    """(B, J, 3) rest-pose joints for (B, K) shape coefficients (no mesh is built)."""
    batch = coeffs.shape[0]
    return arrays.joint_template + (coeffs @ arrays.joint_shape_basis).reshape(batch, -1, 3)


def forward(coeffs: Any, rotmats: Any, arrays: BodyArrays, *, vertices: bool = True
            ) -> tuple[Any | None, Any, Any]:
    """Posed body.

    Parameters
    ----------
    coeffs : (B, K) shape (and expression) coefficients, matching ``arrays.shape_basis``.
    rotmats : (B, J, 3, 3) local joint rotations.
    arrays : the model.
    vertices : build the mesh (False: joints only).

    Returns
    -------
    posed_vertices : (B, V, 3), or None when ``vertices`` is False.
    posed_joints : (B, J, 3).
    transforms : (B, J, 12) skinning transforms, for posing any further rest-pose points.
    """
    joints = rest_joints(coeffs, arrays)
    world_rot, world_pos = world_transforms(rotmats, joints, arrays.tree)
    transforms = skinning_transforms(world_rot, world_pos, joints)
    if not vertices:
        return None, world_pos, transforms
    v = shaped_vertices(coeffs, arrays)
    if arrays.pose_basis is not None:
        v = v + (pose_features(rotmats) @ arrays.pose_basis).reshape(v.shape)
    return skin(v, transforms, arrays.weights), world_pos, transforms
