"""Per-joint quantities of B bodies at one state, computed once and shared by the posed points, the
gradient and the Gauss–Newton matrix of :mod:`smplcore.fit.dense` and :mod:`smplcore.fit.normal_matrix`.

Everything here is (B, J, ...) and float64: a few thousand 3 × 3 matrices, cheap next to the products
over points, but worth computing once per state rather than once per use.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from smplcore.engine import rodrigues, world_transforms
from smplcore.fit.body import FitBody, right_jacobian


@dataclass(eq=False)
class Kinematics:
    """The kinematic chain of B bodies: local and world rotations, joint positions, and (on first use)
    the derivatives the linearisations need.

    Attributes
    ----------
    theta : (B, J, 3) axis-angle of every joint.
    coeffs : (B, K) shape (and expression) coefficients.
    rot : (B, J, 3, 3) local rotations.
    world : (B, J, 3, 3) world rotations ``G_j``.
    pos : (B, J, 3) posed joints (before the translation) ``p_j``.
    shift : (B, J, 3) ``p_j − G_j j̄_j``: joint ``j``'s skinning offset.
    """

    body: FitBody
    theta: np.ndarray
    coeffs: np.ndarray
    rot: np.ndarray
    world: np.ndarray
    pos: np.ndarray
    shift: np.ndarray

    @cached_property
    def right(self) -> np.ndarray:
        """(B, J, 3, 3) right Jacobians ``J_r(θ_j)``: ``R(θ + dθ) ≈ R(θ) exp([J_r dθ]×)``."""
        return right_jacobian(self.theta)

    @cached_property
    def lift(self) -> np.ndarray:
        """(B, J, 3, 3) ``G_j J_r(θ_j)``: world rotation axis per unit of each axis-angle component."""
        return self.world @ self.right

    @cached_property
    def slopes(self) -> np.ndarray:
        """(B, J − 1, 9, 3) ``∂ vec(R_j) / ∂ θ_j`` of the non-root joints (the pose-corrective features'
        derivatives): column ``a`` is ``vec(R_j [J_r e_a]×)``."""
        rot, jr = self.rot[:, 1:], self.right[:, 1:]
        cols = []
        for a in range(3):
            v = jr[..., :, a, None]  # (B, J - 1, 3, 1): components broadcast over R's rows
            r0, r1, r2 = rot[..., :, 0], rot[..., :, 1], rot[..., :, 2]  # columns of R
            v0, v1, v2 = v[..., 0, :], v[..., 1, :], v[..., 2, :]
            cols.append(np.stack([r1 * v2 - r2 * v1, r2 * v0 - r0 * v2, r0 * v1 - r1 * v0], axis=-1))
        return np.stack(cols, axis=-1).reshape(*rot.shape[:2], 9, 3)

    @cached_property
    def totals(self) -> np.ndarray:
        """(B, J, 3, K) ``T_j``: how the shape coefficients move joint ``j``'s skinning offset
        (``Σ_{a on the chain of j} (G_parent(a) − G_a) J̄S_a``)."""
        body = self.body
        parent = np.maximum(body.parents, 0)
        parent_world = np.where((body.parents >= 0)[None, :, None, None], self.world[:, parent], np.eye(3))
        steps = (parent_world - self.world) @ body.joint_shape  # (B, J, 3, K)
        batch, num_joints = steps.shape[:2]
        chain = body.below_of().T.astype(np.float64)  # [j, a]: a on the chain of j
        return (chain @ steps.reshape(batch, num_joints, -1)).reshape(steps.shape)


def kinematics(body: FitBody, theta: np.ndarray, coeffs: np.ndarray) -> Kinematics:
    """The :class:`Kinematics` of (B, J, 3) ``theta`` and (B, K) ``coeffs``."""
    rot = rodrigues(theta)
    jrest = body.joint_template + np.einsum("jck,bk->bjc", body.joint_shape, coeffs)
    world, pos = world_transforms(rot, jrest, body.tree)
    shift = pos - (world @ jrest[..., None])[..., 0]
    return Kinematics(body, theta, coeffs, rot, world, pos, shift)
