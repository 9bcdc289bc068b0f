"""smplx's ``VertexJointSelector``: the module that appends chosen vertices to the joints."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import torch
from torch import nn

from smplcore.errors import ShapeError
from smplcore.family.specs import extra_joint_vertex_ids

__all__ = ["VertexJointSelector"]

#: smplx's ``tip_names`` (the fingertip keys of its vertex ids, per hand: ``l`` / ``r`` + name).
TIP_NAMES = ["thumb", "index", "middle", "ring", "pinky"]


class VertexJointSelector(nn.Module):
    """Holds the ``extra_joints_idxs`` buffer (the vertices appended to the joints) and appends them:
    ``selector(vertices, joints)`` is (B, J + n, 3).

    Parameters
    ----------
    vertex_ids : smplx's ``{name: vertex}`` dict (``smplx.vertex_ids.vertex_ids["smplx"]``): the face keypoints,
        then the feet and the fingertips as the flags below say, in smplx's order; or the vertex indices.
    use_hands, use_feet_keypoints : include the fingertips / the feet (with a dict).
    """

    extra_joints_idxs: torch.Tensor

    def __init__(
        self,
        vertex_ids: Mapping[str, int] | Sequence[int] | None = None,
        use_hands: bool = True,
        use_feet_keypoints: bool = True,
        **kwargs: Any,
    ) -> None:
        super().__init__()
        if vertex_ids is None:
            raise TypeError(
                "vertex_ids: expected smplx's {name: vertex} dict (e.g. smplx.vertex_ids.vertex_ids['smplx']) or "
                "a list of vertex indices"
            )
        if isinstance(vertex_ids, Mapping):
            try:
                ids = extra_joint_vertex_ids(dict(vertex_ids), use_hands, use_feet_keypoints)[1]
            except KeyError as exc:
                raise KeyError(f"vertex_ids: no vertex for {exc.args[0]!r} (smplx's names: nose, reye, ...)") from None
        else:
            ids = [int(i) for i in vertex_ids]
        if use_hands:
            self.tip_names = list(TIP_NAMES)
        self.register_buffer("extra_joints_idxs", torch.tensor(ids, dtype=torch.long))

    def forward(self, vertices: torch.Tensor, joints: torch.Tensor) -> torch.Tensor:
        """(B, J + n, 3): (B, J, 3) ``joints`` followed by the n selected vertices of (B, V, 3) ``vertices``."""
        if vertices.ndim != 3 or joints.ndim != 3 or vertices.shape[0] != joints.shape[0]:
            raise ShapeError(
                f"vertices, joints: expected (B, V, 3) and (B, J, 3), got {tuple(vertices.shape)} and "
                f"{tuple(joints.shape)}"
            )
        return torch.cat([joints, vertices.index_select(1, self.extra_joints_idxs)], dim=1)
