"""The forward pass written plainly: the oracle every fast path is tested against.

Each step of the seed documents is one short function, over NumPy or torch arrays alike, in any
float dtype (float64 for tests), with no caches, no blocking and no precomputed bases:

1. shape blend: ``v_shaped = v_template + shapedirs @ coeffs``
2. joint regression: ``J = J_regressor @ v_shaped``
3. pose correctives: ``v_posed = v_shaped + posedirs @ vec(R_j - I)`` over every joint but the root
4. kinematic chain: ``G_j = G_parent(j) [R_j | J_j - J_parent(j)]``, then relative to the rest pose
   ``A_j = G_j [I | -J_j]``
5. skinning: ``v' = Σ_j w_j A_j v`` (linear blend skinning)

It is also the plain torch path that runs under ``torch.compile``, ``torch.export``, ``torch.func``
transforms and on GPUs (see :mod:`smplcore.engine.kernels`): only tensor operations, no host round
trips, no Python branches on tensor values.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from smplcore.engine.backend import eye, namespace


def shape_blend(v_template: Any, shapedirs: Any, coeffs: Any) -> Any:
    """(B, V, 3) ``v_template`` (V, 3) plus ``shapedirs`` (V, 3, K) times ``coeffs`` (B, K)."""
    xp = namespace(coeffs)
    return v_template[None] + xp.einsum("vdk,bk->bvd", shapedirs, coeffs)


def regress_joints(J_regressor: Any, vertices: Any) -> Any:
    """(B, J, 3) joints: ``J_regressor`` (J, V) applied to ``vertices`` (B, V, 3)."""
    return namespace(vertices).einsum("jv,bvd->bjd", J_regressor, vertices)


def rodrigues(rotvec: Any) -> Any:
    """(..., 3, 3) rotation matrices from (..., 3) axis-angle vectors ``r``, θ = |r|.

    ``R = I + a(θ) [r]× + b(θ) [r]×²`` with ``a = sin θ / θ`` and ``b = (1 - cos θ) / θ²``. Below
    θ² = 1e-6 both come from their Taylor series (so that values and gradients are exact at θ = 0,
    where the quotients are 0 / 0); elsewhere the exact branch never sees θ = 0.
    """
    xp = namespace(rotvec)
    theta2 = (rotvec * rotvec).sum(axis=-1)[..., None, None]
    small = theta2 < 1e-6
    safe2 = xp.where(small, xp.ones_like(theta2), theta2)
    theta = xp.sqrt(safe2)
    a = xp.where(small, 1 - theta2 / 6 + theta2 * theta2 / 120, xp.sin(theta) / theta)
    b = xp.where(small, 0.5 - theta2 / 24 + theta2 * theta2 / 720, (1 - xp.cos(theta)) / safe2)
    x, y, z = rotvec[..., 0], rotvec[..., 1], rotvec[..., 2]
    o = xp.zeros_like(x)
    k = xp.stack([o, -z, y, z, o, -x, -y, x, o], axis=-1).reshape(*rotvec.shape[:-1], 3, 3)
    return eye(3, rotvec) + a * k + b * (k @ k)


def pose_features(rotmats: Any) -> Any:
    """(B, 9 (J - 1)) ``R_j - I`` of every joint but the root, flattened row-major."""
    return (rotmats[:, 1:] - eye(3, rotmats)).reshape(rotmats.shape[0], -1)


def pose_correctives(posedirs: Any, rotmats: Any) -> Any:
    """(B, V, 3) pose-corrective offsets; ``posedirs`` is (9 (J - 1), 3 V) as the official files."""
    offsets = pose_features(rotmats) @ posedirs
    return offsets.reshape(rotmats.shape[0], -1, 3)


def kinematic_chain(rotmats: Any, joints: Any, parents: Sequence[int]) -> tuple[Any, Any]:
    """World transforms of the joints, one joint at a time.

    Parameters
    ----------
    rotmats : (B, J, 3, 3) local rotations.
    joints : (B, J, 3) rest-pose joints.
    parents : parent of each joint (-1 for the root); parents come before their children.

    Returns
    -------
    posed_joints : (B, J, 3).
    relative : (B, J, 4, 4) ``A_j``: the rest pose to the posed pose, per joint.
    """
    xp = namespace(rotmats)
    bottom = xp.concat([xp.zeros_like(joints[:, :1]), xp.ones_like(joints[:, :1, :1])], axis=2)  # (B, 1, 4): 0 0 0 1
    chain: list[Any] = []
    for j, p in enumerate(parents):
        offset = joints[:, j] if p < 0 else joints[:, j] - joints[:, p]
        local = xp.concat([xp.concat([rotmats[:, j], offset[:, :, None]], axis=2), bottom], axis=1)
        chain.append(local if p < 0 else chain[p] @ local)
    world = xp.stack(chain, axis=1)  # (B, J, 4, 4)
    rest = xp.concat([joints, xp.zeros_like(joints[..., :1])], axis=-1)[..., None]  # (B, J, 4, 1)
    shift = world @ rest  # G_j [J_j, 0]
    zeros = xp.zeros_like(world[..., :3])
    relative = world - xp.concat([zeros, shift], axis=-1)
    return world[:, :, :3, 3], relative


def linear_blend_skinning(vertices: Any, relative: Any, weights: Any) -> Any:
    """(B, V, 3) posed vertices: (V, J) ``weights`` blend the (B, J, 4, 4) ``relative`` transforms,
    each vertex of (B, V, 3) ``vertices`` is moved by its blended transform."""
    xp = namespace(vertices)
    batch, num_joints = relative.shape[:2]
    blended = (weights @ relative.reshape(batch, num_joints, 16)).reshape(batch, -1, 4, 4)
    return xp.einsum("bvij,bvj->bvi", blended[..., :3, :3], vertices) + blended[..., :3, 3]


def forward(
    v_template: Any,
    shapedirs: Any,
    posedirs: Any | None,
    J_regressor: Any,
    parents: Sequence[int],
    weights: Any,
    coeffs: Any,
    rotmats: Any,
) -> tuple[Any, Any, Any]:
    """The body model.

    Parameters
    ----------
    v_template : (V, 3); shapedirs : (V, 3, K) shape (and expression) blend shapes;
    posedirs : (9 (J - 1), 3 V) or None; J_regressor : (J, V); parents : (J,); weights : (V, J).
    coeffs : (B, K) shape (and expression) coefficients; rotmats : (B, J, 3, 3) local rotations.

    Returns
    -------
    vertices : (B, V, 3) posed (untranslated); joints : (B, J, 3) posed; relative : (B, J, 4, 4).
    """
    v_shaped = shape_blend(v_template, shapedirs, coeffs)
    rest_joints = regress_joints(J_regressor, v_shaped)
    v_posed = v_shaped if posedirs is None else v_shaped + pose_correctives(posedirs, rotmats)
    joints, relative = kinematic_chain(rotmats, rest_joints, parents)
    return linear_blend_skinning(v_posed, relative, weights), joints, relative
