"""Moving a wrist's twist about the forearm into the forearm (the elbow joint), without moving the hand.

A wrist turned about the forearm's axis by linear blend skinning collapses where the wrist's and the
elbow's weights meet (the "candy wrapper", see docs/skinning.md). In a real arm that turn is pronation: the
forearm turns along its length. Turning the elbow joint about the elbow-wrist axis does not move the wrist
(it lies on the axis), and the wrist taking the opposite turn keeps the hand's orientation, so the hand and
its joints stay where they are while the twist is shared along the arm.

The share is the least-squares split of the twist angle ``φ`` over the chain: minimise
``w_w x_w² + w_e x_e²`` subject to ``x_w + x_e = φ`` and the elbow's own twist staying within a limit, whose
solution is ``x_e = s φ`` (``s = w_w / (w_w + w_e)``) clipped to the limit.
"""

from __future__ import annotations

import numpy as np

from smplcore.join.rotations import to_matrix, twist_angle


def forearm_axis(rest_joints: np.ndarray, elbow: int, wrist: int) -> np.ndarray:
    """(B, 3) unit elbow-to-wrist direction of (B, J, 3) rest joints: the axis the forearm turns about, in the
    elbow's (rest-aligned) frame."""
    d = rest_joints[:, wrist] - rest_joints[:, elbow]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def redistribute_twist(
    elbow_local: np.ndarray, wrist_local: np.ndarray, axis: np.ndarray, share: float, limit: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Move ``share`` of the wrist's twist about ``axis`` into the elbow, the elbow's twist kept in ``±limit``.

    Parameters
    ----------
    elbow_local, wrist_local : (B, 3, 3) local rotations.
    axis : (B, 3) unit forearm axis in the elbow's frame (see :func:`forearm_axis`).
    share : 0..1 of the wrist's twist moved.
    limit : bound (radians) on the elbow's twist about ``axis`` afterwards.

    Returns
    -------
    The new elbow and wrist rotations (B, 3, 3) (``elbow · wrist`` unchanged), and the wrist's twist angle
    before and after (B,).
    """
    before = twist_angle(wrist_local, axis)
    if share <= 0:
        return elbow_local, wrist_local, before, before
    elbow_twist = twist_angle(elbow_local, axis)
    moved = np.clip(share * before, -limit - elbow_twist, limit - elbow_twist)
    moved = np.where(np.abs(elbow_twist) > limit, 0.0, moved)  # already beyond the limit: leave it
    turn = to_matrix(moved[:, None] * axis)
    new_elbow = elbow_local @ turn
    new_wrist = np.swapaxes(turn, -1, -2) @ wrist_local
    return new_elbow, new_wrist, before, twist_angle(new_wrist, axis)
