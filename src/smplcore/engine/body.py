"""The body-model forward pass, once for every model and both namespaces.

:class:`BodyArrays` holds a model's arrays arranged for fast evaluation (bases as matrices, shape
terms of the joints precomputed); :func:`forward` maps shape coefficients and joint rotations to
posed vertices and joints:

    shape blend → joint regression → pose correctives → kinematic chain → skinning
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.engine.backend import namespace
from smplcore.engine.rotations import pose_features
from smplcore.engine.skeleton import KinematicTree, skin, skinning_transforms, world_transforms


@dataclass
class BodyArrays:
    """A model's arrays in one namespace, dtype and device, laid out for one GEMM per body part.

    Attributes
    ----------
    blend_basis : (1 + K [+ P], 3 * V) rows: the template, the K shape (and expression) blend
        shapes, then the P pose correctives when the model has any; columns are coordinate-major
        (all x, then all y, then all z). Rest-pose vertices are ``[1, coeffs, pose_features] @
        blend_basis``: template, shape and pose blend in one product, laid out as (B, 3, V).
    num_coeffs : K.
    joint_template : (J, 3) rest joints of the template, ``J_regressor @ v_template``.
    joint_shape_basis : (K, J * 3) how each coefficient moves the rest joints.
    weights_t : (J, V) skinning weights, transposed.
    tree : the kinematic tree.
    """

    blend_basis: Any
    num_coeffs: int
    joint_template: Any
    joint_shape_basis: Any
    weights_t: Any
    tree: KinematicTree

    @classmethod
    def build(cls, v_template: np.ndarray, shapedirs: np.ndarray, J_regressor: np.ndarray,
              posedirs: np.ndarray | None, weights: np.ndarray, parents: np.ndarray,
              convert: Callable[[np.ndarray], Any] = np.asarray) -> BodyArrays:
        """Arrange NumPy model arrays for evaluation; ``convert`` moves each to the target namespace.

        ``shapedirs`` is (V, 3, K) (shape and expression columns already concatenated), ``posedirs``
        (V, 3, P) or None; all-zero pose correctives are dropped.
        """
        v_template = np.asarray(v_template, dtype=np.float64)
        shapedirs = np.asarray(shapedirs, dtype=np.float64)
        J_regressor = np.asarray(J_regressor, dtype=np.float64)
        num_verts, num_coeffs = v_template.shape[0], shapedirs.shape[-1]
        rows = [v_template.T.reshape(1, -1), shapedirs.transpose(2, 1, 0).reshape(num_coeffs, 3 * num_verts)]
        if posedirs is not None and np.any(posedirs):
            rows.append(np.asarray(posedirs).transpose(2, 1, 0).reshape(-1, 3 * num_verts))
        joint_shape = np.einsum("jv,vdk->kjd", J_regressor, shapedirs).reshape(num_coeffs, -1)
        return cls(
            blend_basis=convert(np.concatenate(rows, axis=0)),
            num_coeffs=num_coeffs,
            joint_template=convert(J_regressor @ v_template),
            joint_shape_basis=convert(joint_shape),
            weights_t=convert(np.ascontiguousarray(np.asarray(weights).T)),
            tree=KinematicTree.from_parents(parents),
        )

    @property
    def has_pose_correctives(self) -> bool:
        return self.blend_basis.shape[0] > 1 + self.num_coeffs

    def map(self, fn: Callable[[Any], Any]) -> BodyArrays:
        """The same arrays with ``fn`` applied to each (e.g. a dtype or device change)."""
        return BodyArrays(fn(self.blend_basis), self.num_coeffs, fn(self.joint_template),
                          fn(self.joint_shape_basis), fn(self.weights_t), self.tree)


def _with_one(coeffs: Any) -> Any:
    xp = namespace(coeffs)
    return xp.concat([xp.ones_like(coeffs[:, :1]), coeffs], axis=1)


def rest_vertices(coeffs: Any, rotmats: Any | None, arrays: BodyArrays, columns: Any = None) -> Any:
    """(B, 3, n) rest-pose vertices, one row per coordinate: template + shape blend (+ pose
    correctives when ``rotmats`` is given).

    ``columns`` (from :func:`vertex_columns`) selects a subset of the mesh's vertices.
    """
    basis = arrays.blend_basis if columns is None else arrays.blend_basis[:, columns]
    feats = _with_one(coeffs)
    if rotmats is not None and arrays.has_pose_correctives:
        feats = namespace(coeffs).concat([feats, pose_features(rotmats)], axis=1)
    else:
        basis = basis[: 1 + arrays.num_coeffs]
    return (feats @ basis).reshape(coeffs.shape[0], 3, -1)


def vertex_columns(ids: np.ndarray, num_verts: int) -> np.ndarray:
    """Columns of ``blend_basis`` holding vertices ``ids`` (x of all, then y, then z)."""
    return (np.arange(3)[:, None] * num_verts + np.asarray(ids)[None]).reshape(-1)


def shaped_vertices(coeffs: Any, arrays: BodyArrays) -> Any:
    """(B, V, 3) rest-pose vertices for (B, K) shape coefficients (no pose correctives)."""
    return rest_vertices(coeffs, None, arrays).mT


def rest_joints(coeffs: Any, arrays: BodyArrays) -> Any:
    """(B, J, 3) rest-pose joints for (B, K) shape coefficients (no mesh is built)."""
    batch = coeffs.shape[0]
    return arrays.joint_template + (coeffs @ arrays.joint_shape_basis).reshape(batch, -1, 3)


def forward(coeffs: Any, rotmats: Any, arrays: BodyArrays, *, vertices: bool = True, translation: Any = None
            ) -> tuple[Any | None, Any, Any]:
    """Posed body.

    Parameters
    ----------
    coeffs : (B, K) shape (and expression) coefficients, matching ``arrays``.
    rotmats : (B, J, 3, 3) local joint rotations.
    arrays : the model.
    vertices : build the mesh (False: joints only).
    translation : (B, 3) added to the vertices (not to the joints or transforms), or None.

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
    v = rest_vertices(coeffs, rotmats, arrays)
    return skin(v, transforms, arrays.weights_t, translation), world_pos, transforms
