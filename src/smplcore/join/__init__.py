"""Whole bodies from parts: MANO hands and FLAME heads joined to SMPL-X / SMPL+H bodies, and split off again.

See docs/join.md for the conventions (frames, flat vs mean hand pose, PCA, the mirrored left hand, MANO's
left ``shapedirs``) and a worked HaMeR / WiLoR example.
"""

from smplcore.join.hands import HandResidual, JoinResult, join_hands, split_hands
from smplcore.join.heads import ExpressionMap, FlameHead, HeadResidual, expression_map, join_head, split_head
from smplcore.join.mano import ManoHand, fixed_left_shapedirs, left_shapedirs_flipped

__all__ = [
    "ExpressionMap",
    "FlameHead",
    "HeadResidual",
    "expression_map",
    "join_head",
    "split_head",
    "HandResidual",
    "JoinResult",
    "ManoHand",
    "fixed_left_shapedirs",
    "join_hands",
    "left_shapedirs_flipped",
    "split_hands",
]
