"""Each model of the SMPL family as data: pose blocks, joint names, extra joints, landmarks.

The engine knows none of the model names; the front ends read a :class:`FamilySpec` to learn which
keyword arguments a model takes, how its full pose is laid out, which vertices become extra joints
and whether it has face landmarks. Adding a model means adding a spec here.
"""

from __future__ import annotations

from dataclasses import dataclass

from smplcore.family import names


@dataclass(frozen=True)
class PoseBlock:
    """A run of consecutive joints in the full pose, set by one keyword argument.

    ``hand`` marks blocks that may be given as hand-PCA coefficients (``"left"`` or ``"right"``).
    """

    name: str
    num_joints: int
    hand: str | None = None


@dataclass(frozen=True)
class FamilySpec:
    """What distinguishes one model of the family from another.

    Attributes
    ----------
    model_type : key used by ``create(model_type=...)``.
    display_name : name as printed by smplx (``"SMPL+H"``).
    pose_blocks : the full pose, in joint order.
    num_vertices : vertex count of the official mesh, or None when any is allowed.
    file_stem : official file name stem; ``{GENDER}`` is replaced by the upper-case gender.
    shape_space_dim : columns of ``shapedirs`` reserved for shape in a file that also holds
        expressions (SMPL-X, FLAME: 300); 0 where the whole ``shapedirs`` is shape.
    expression_space_dim : expression columns in such a file (100), 0 if none.
    vertex_ids : extra-joint vertex per name (smplx's keys: ``nose``, ``LBigToe``, ``lthumb``, ...).
    extra_joints : whether extra vertex joints are appended to the output joints at all.
    landmarks : whether the model has static face landmarks (and optionally a dynamic contour).
    neck_index : joint whose kinematic chain selects the dynamic contour, or None.
    joint_names : names of the model's skeleton joints.
    """

    model_type: str
    display_name: str
    pose_blocks: tuple[PoseBlock, ...]
    num_vertices: int | None
    file_stem: str
    joint_names: tuple[str, ...]
    shape_space_dim: int = 0
    expression_space_dim: int = 0
    vertex_ids: dict | None = None
    extra_joints: bool = True
    landmarks: bool = False
    neck_index: int | None = None

    @property
    def num_joints(self) -> int:
        return sum(block.num_joints for block in self.pose_blocks)

    @property
    def has_expression(self) -> bool:
        return self.expression_space_dim > 0

    @property
    def hand_blocks(self) -> tuple[PoseBlock, ...]:
        return tuple(block for block in self.pose_blocks if block.hand)

    def block(self, name: str) -> PoseBlock:
        for candidate in self.pose_blocks:
            if candidate.name == name:
                return candidate
        raise KeyError(name)

    def block_offsets(self) -> dict[str, tuple[int, int]]:
        """Joint range ``(start, stop)`` of each pose block in the full pose."""
        offsets, start = {}, 0
        for block in self.pose_blocks:
            offsets[block.name] = (start, start + block.num_joints)
            start += block.num_joints
        return offsets


_GLOBAL = PoseBlock("global_orient", 1)
_HANDS = (PoseBlock("left_hand_pose", 15, hand="left"), PoseBlock("right_hand_pose", 15, hand="right"))
_FACE = (PoseBlock("jaw_pose", 1), PoseBlock("leye_pose", 1), PoseBlock("reye_pose", 1))

SMPL = FamilySpec(
    model_type="smpl",
    display_name="SMPL",
    num_vertices=6890,
    file_stem="SMPL_{GENDER}",
    pose_blocks=(_GLOBAL, PoseBlock("body_pose", 23)),
    joint_names=names.SMPL_JOINTS,
    vertex_ids=names.VERTEX_IDS_SMPLH,
)
SMPLH = FamilySpec(
    model_type="smplh",
    display_name="SMPL+H",
    num_vertices=6890,
    file_stem="SMPLH_{GENDER}",
    pose_blocks=(_GLOBAL, PoseBlock("body_pose", 21), *_HANDS),
    joint_names=names.SMPLH_JOINTS,
    vertex_ids=names.VERTEX_IDS_SMPLH,
)
SMPLX = FamilySpec(
    model_type="smplx",
    display_name="SMPL-X",
    num_vertices=10475,
    file_stem="SMPLX_{GENDER}",
    pose_blocks=(_GLOBAL, PoseBlock("body_pose", 21), *_FACE, *_HANDS),
    joint_names=names.SMPLX_JOINTS,
    vertex_ids=names.VERTEX_IDS_SMPLX,
    shape_space_dim=300,
    expression_space_dim=100,
    landmarks=True,
    neck_index=12,
)
MANO = FamilySpec(
    model_type="mano",
    display_name="MANO",
    num_vertices=778,
    file_stem="MANO_{SIDE}",
    pose_blocks=(_GLOBAL, PoseBlock("hand_pose", 15, hand="self")),
    joint_names=names.MANO_JOINTS,
    extra_joints=False,
)
FLAME = FamilySpec(
    model_type="flame",
    display_name="FLAME",
    num_vertices=5023,
    file_stem="FLAME_{GENDER}",
    pose_blocks=(_GLOBAL, PoseBlock("neck_pose", 1), *_FACE),
    joint_names=names.FLAME_JOINTS,
    extra_joints=False,
    shape_space_dim=300,
    expression_space_dim=100,
    landmarks=True,
    neck_index=0,
)
OPEN = FamilySpec(
    model_type="open",
    display_name="smplcore open model",
    num_vertices=None,
    file_stem="open_model",
    pose_blocks=(_GLOBAL, PoseBlock("body_pose", 23)),
    joint_names=names.SMPL_JOINTS,
    vertex_ids=None,
)

SPECS: dict[str, FamilySpec] = {spec.model_type: spec for spec in (SMPL, SMPLH, SMPLX, MANO, FLAME, OPEN)}

#: Skeleton size of each model type, used to tell a file's model type from its contents.
MODEL_TYPE_BY_NUM_JOINTS = {24: "smpl", 52: "smplh", 55: "smplx", 16: "mano", 5: "flame"}


def get_spec(model_type: str) -> FamilySpec:
    """The spec for ``model_type`` (case-insensitive), with a clear error for unknown types."""
    key = str(model_type).lower().replace("+", "").replace("-", "")
    if key not in SPECS:
        raise ValueError(f"model_type: unknown model type {model_type!r}; expected one of {sorted(SPECS)}")
    return SPECS[key]


def extra_joint_vertex_ids(
    vertex_ids: dict, use_hands: bool = True, use_feet_keypoints: bool = True
) -> tuple[list[str], list[int]]:
    """Names and vertex ids of the extra joints, in smplx's order (face, feet, fingertips)."""
    keys = list(names.FACE_KEYPOINTS)
    if use_feet_keypoints:
        keys += names.FEET_KEYPOINTS
    if use_hands:
        keys += names.FINGERTIP_KEYPOINTS
    return [names.EXTRA_JOINT_NAMES[k] for k in keys], [int(vertex_ids[k]) for k in keys]
