"""Face landmarks: barycentric points on the mesh, and the dynamic face contour."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from smplcore.engine.backend import eye, index, namespace
from smplcore.engine.rotations import y_angle


def barycentric_points(vertices: Any, corners: Any, bary: Any) -> Any:
    """Points inside mesh triangles.

    Parameters
    ----------
    vertices : (B, V, 3).
    corners : (L, 3) or (B, L, 3) integer vertex ids of each point's triangle.
    bary : (L, 3) or (B, L, 3) barycentric coordinates.

    Returns
    -------
    (B, L, 3) points.
    """
    xp = namespace(vertices)
    if corners.ndim == 2:
        pts = vertices[:, corners]  # (B, L, 3, 3)
    else:
        batch = index(range(vertices.shape[0]), vertices)[:, None, None]
        pts = vertices[batch, corners]
    if bary.ndim == 2:
        return xp.einsum("lk,blkd->bld", bary, pts)
    return xp.einsum("blk,blkd->bld", bary, pts)


def contour_rows(rotmats: Any, neck_chain: Sequence[int]) -> Any:
    """Row of the 79-row dynamic-contour table for each body, from the head's rotation about Y.

    The rotations of the neck and all its ancestors are composed; the resulting turn of the head
    about the vertical axis, in whole degrees within ±39, picks the row (0…39 for one side, 40…78
    for the other), as in the FLAME and SMPL-X landmark embeddings.

    Parameters
    ----------
    rotmats : (B, J, 3, 3) local joint rotations.
    neck_chain : the neck joint, its parent, ..., the root.

    Returns
    -------
    (B,) integer rows.
    """
    xp = namespace(rotmats)
    rel = eye(3, rotmats)[None]
    for joint in neck_chain:
        rel = rotmats[:, joint] @ rel
    degrees = xp.round(xp.clip(-y_angle(rel) * (180.0 / math.pi), None, 39.0))
    rows = xp.where(degrees < 0, xp.where(degrees < -39, 78.0 + 0 * degrees, 39.0 - degrees), degrees)
    return rows.astype(int) if xp.__name__ == "numpy" else rows.long()
