"""The forward pass written plainly: the oracle every fast path is tested against.

Each step of the seed documents is one short function, over NumPy or torch arrays alike, in any
float dtype (float64 for tests), with no caches, no blocking and no precomputed bases:

1. shape blend: ``v_shaped = v_template + shapedirs @ coeffs``
2. joint regression: ``J = J_regressor @ v_shaped``
3. pose correctives: ``v_posed = v_shaped + posedirs @ vec(R_j - I)`` over every joint but the root
4. kinematic chain: ``G_j = G_parent(j) [R_j | J_j - J_parent(j)]``, then relative to the rest pose
   ``A_j = G_j [I | -J_j]``
5. skinning: ``v' = Σ_j w_j A_j v`` (linear blend skinning), or dual-quaternion skinning: the unit
   dual quaternions ``q_j`` of the ``A_j`` blended as ``Σ_j w_j s_j q_j`` (``s_j = ±1`` puts each in
   the hemisphere of the vertex's most influential joint), normalised, applied to ``v``

It is also the plain torch path that runs under ``torch.compile``, ``torch.export``, ``torch.func``
transforms and on GPUs (see :mod:`smplcore.engine.kernels`): only tensor operations, no host round
trips, no Python branches on tensor values.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from smplcore.engine.backend import eye, namespace


def shape_blend(v_template: Any, shapedirs: Any, coeffs: Any) -> Any:
    """(B, V, 3) ``v_template`` plus ``shapedirs`` (V, 3, K) times ``coeffs`` (B, K); the template is (V, 3), or
    (B, V, 3) / (1, V, 3): one per body."""
    xp = namespace(coeffs)
    template = v_template if v_template.ndim == 3 else v_template[None]
    return template + xp.einsum("vdk,bk->bvd", shapedirs, coeffs)


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


def rotation_quaternions(rotmats: Any) -> Any:
    """(..., 4) unit quaternions ``(w, x, y, z)`` of (..., 3, 3) rotation matrices (either sign).

    Shepperd's method: of the four expressions of ``q`` in terms of the matrix entries, the one whose
    divisor (``4 w``, ``4 x``, ``4 y`` or ``4 z``) is largest; it is at least 1, so the result and its
    gradient are well conditioned everywhere.
    """
    xp = namespace(rotmats)
    m = [[rotmats[..., i, j] for j in range(3)] for i in range(3)]
    trace = [
        1 + m[0][0] + m[1][1] + m[2][2],
        1 + m[0][0] - m[1][1] - m[2][2],
        1 - m[0][0] + m[1][1] - m[2][2],
        1 - m[0][0] - m[1][1] + m[2][2],
    ]
    zyx = [m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]]  # 4 w (x, y, z)
    xy, xz, yz = m[0][1] + m[1][0], m[0][2] + m[2][0], m[1][2] + m[2][1]  # 4 x y, 4 x z, 4 y z
    numerators = [  # 4 s times (w, x, y, z), for s = w, x, y, z
        (trace[0], zyx[0], zyx[1], zyx[2]),
        (zyx[0], trace[1], xy, xz),
        (zyx[1], xy, trace[2], yz),
        (zyx[2], xz, yz, trace[3]),
    ]
    best, quat = None, None
    for t, num in zip(trace, numerators):
        half = 2 * xp.sqrt(xp.clip(t, 1e-12, None))  # 4 s / (2 s) with 4 s² = t
        q = xp.stack([n / half for n in num], axis=-1)
        if best is None:
            best, quat = t, q
        else:
            take = t > best
            quat = xp.where(take[..., None], q, quat)
            best = xp.where(take, t, best)
    return quat


def quaternion_product(a: Any, b: Any) -> Any:
    """(..., 4) Hamilton product ``a b`` of (..., 4) quaternions ``(w, x, y, z)``."""
    xp = namespace(a)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return xp.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def dual_quaternions(rotation: Any, translation: Any) -> Any:
    """(..., 8) unit dual quaternions ``(q, ½ (0, t) q)`` of rigid transforms ``x ↦ R x + t``.

    ``rotation`` (..., 3, 3), ``translation`` (..., 3); the first 4 values are the rotation
    quaternion ``q``, the last 4 the dual part.
    """
    xp = namespace(rotation)
    real = rotation_quaternions(rotation)
    pure = xp.concat([xp.zeros_like(translation[..., :1]), translation], axis=-1)
    return xp.concat([real, 0.5 * quaternion_product(pure, real)], axis=-1)


def dominant_joints(weights: Any) -> Any:
    """(V,) index of each vertex's most influential joint in (V, J) ``weights`` (ties: the first)."""
    return namespace(weights).argmax(weights, axis=1)


def apply_dual_quaternions(blended: Any, vertices: Any) -> Any:
    """(B, V, 3) ``vertices`` moved by the (B, V, 8) dual quaternions ``blended`` after normalising
    them: ``v + 2 r × (r × v + w v) + 2 (w rₑ - wₑ r + r × rₑ)`` for ``q = (w, r)``, dual part ``(wₑ, rₑ)``
    (any scale: both parts are divided by ``|q|``; the dual part's component along ``q`` is dropped)."""
    w, r = blended[..., :1], blended[..., 1:4]
    we, re = blended[..., 4:5], blended[..., 5:8]
    inner = _cross(r, vertices) + w * vertices
    moved = _cross(r, inner) + w * re - we * r + _cross(r, re)
    return vertices + (2 / (w * w + (r * r).sum(axis=-1, keepdims=True))) * moved


def _cross(a: Any, b: Any) -> Any:
    xp = namespace(a)
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return xp.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def dual_quaternion_skinning(vertices: Any, relative: Any, weights: Any) -> Any:
    """(B, V, 3) posed vertices by dual-quaternion skinning.

    Parameters
    ----------
    vertices : (B, V, 3) rest-pose vertices (shaped, with pose correctives).
    relative : (B, J, 4, 4) rigid transforms ``A_j`` (as :func:`kinematic_chain` gives).
    weights : (V, J) skinning weights.

    Each joint's dual quaternion ``q_j`` is put in the hemisphere of the vertex's most influential joint
    ``d`` (``q_j`` or ``-q_j``, whichever has ``q_j · q_d ≥ 0``: both describe the same transform, but
    only the nearer one blends without a flip), blended with the weights, normalised and applied. At the
    rest pose (every ``A_j = I``) this is the identity, as linear blend skinning is. Plain: it builds
    (B, V, J) signs.
    """
    xp = namespace(vertices)
    dq = dual_quaternions(relative[..., :3, :3], relative[..., :3, 3])  # (B, J, 8)
    real = dq[..., :4]
    same_side = xp.einsum("bik,bjk->bij", real, real) >= 0  # (B, J, J): q_i · q_j ≥ 0
    signs = xp.where(same_side, xp.ones_like(same_side, dtype=dq.dtype), -xp.ones_like(same_side, dtype=dq.dtype))
    signed = weights[None] * signs[:, dominant_joints(weights)]  # (B, V, J)
    return apply_dual_quaternions(signed @ dq, vertices)


SKINNING = {"lbs": linear_blend_skinning, "dqs": dual_quaternion_skinning}


def forward(
    v_template: Any,
    shapedirs: Any,
    posedirs: Any | None,
    J_regressor: Any,
    parents: Sequence[int],
    weights: Any,
    coeffs: Any,
    rotmats: Any,
    skinning: str = "lbs",
) -> tuple[Any, Any, Any]:
    """The body model.

    Parameters
    ----------
    v_template : (V, 3), or (B, V, 3) one per body; shapedirs : (V, 3, K) shape (and expression) blend shapes;
    posedirs : (9 (J - 1), 3 V) or None; J_regressor : (J, V); parents : (J,); weights : (V, J).
    coeffs : (B, K) shape (and expression) coefficients; rotmats : (B, J, 3, 3) local rotations.
    skinning : ``"lbs"`` (linear blend skinning) or ``"dqs"`` (dual-quaternion skinning).

    Returns
    -------
    vertices : (B, V, 3) posed (untranslated); joints : (B, J, 3) posed; relative : (B, J, 4, 4).
    """
    v_shaped = shape_blend(v_template, shapedirs, coeffs)
    rest_joints = regress_joints(J_regressor, v_shaped)
    v_posed = v_shaped if posedirs is None else v_shaped + pose_correctives(posedirs, rotmats)
    joints, relative = kinematic_chain(rotmats, rest_joints, parents)
    return SKINNING[skinning](v_posed, relative, weights), joints, relative
