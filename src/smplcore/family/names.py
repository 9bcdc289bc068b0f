"""Joint names and extra-joint vertex ids of the SMPL family (facts about the official meshes)."""

from __future__ import annotations

SMPL_BODY = (
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
)
_FINGERS = ("index", "middle", "pinky", "ring", "thumb")


def _hand(side: str) -> tuple[str, ...]:
    return tuple(f"{side}_{finger}{k}" for finger in _FINGERS for k in (1, 2, 3))


SMPL_JOINTS = SMPL_BODY + ("left_hand", "right_hand")
SMPLH_JOINTS = SMPL_BODY + _hand("left") + _hand("right")
SMPLX_JOINTS = SMPL_BODY + ("jaw", "left_eye_smplhf", "right_eye_smplhf") + _hand("left") + _hand("right")
MANO_JOINTS = ("wrist",) + _hand("hand")
FLAME_JOINTS = ("global", "neck", "jaw", "left_eye", "right_eye")

# Extra joints selected from vertices, under smplx's vertex_ids keys, in smplx's order.
FACE_KEYPOINTS = ("nose", "reye", "leye", "rear", "lear")
FEET_KEYPOINTS = ("LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel")
FINGERTIP_KEYPOINTS = tuple(
    f"{side}{finger}" for side in "lr" for finger in ("thumb", "index", "middle", "ring", "pinky")
)
EXTRA_JOINT_NAMES = {
    "nose": "nose",
    "reye": "right_eye",
    "leye": "left_eye",
    "rear": "right_ear",
    "lear": "left_ear",
    "LBigToe": "left_big_toe",
    "LSmallToe": "left_small_toe",
    "LHeel": "left_heel",
    "RBigToe": "right_big_toe",
    "RSmallToe": "right_small_toe",
    "RHeel": "right_heel",
    **{
        f"{s}{finger}": f"{side}_{finger}"
        for s, side in (("l", "left"), ("r", "right"))
        for finger in ("thumb", "index", "middle", "ring", "pinky")
    },
}
#: smplx's key of each extra-joint name (inverse of EXTRA_JOINT_NAMES).
EXTRA_JOINT_KEYS = {name: key for key, name in EXTRA_JOINT_NAMES.items()}

VERTEX_IDS_SMPLH = {
    "nose": 332,
    "reye": 6260,
    "leye": 2800,
    "rear": 4071,
    "lear": 583,
    "rthumb": 6191,
    "rindex": 5782,
    "rmiddle": 5905,
    "rring": 6016,
    "rpinky": 6133,
    "lthumb": 2746,
    "lindex": 2319,
    "lmiddle": 2445,
    "lring": 2556,
    "lpinky": 2673,
    "LBigToe": 3216,
    "LSmallToe": 3226,
    "LHeel": 3387,
    "RBigToe": 6617,
    "RSmallToe": 6624,
    "RHeel": 6787,
}
VERTEX_IDS_SMPLX = {
    "nose": 9120,
    "reye": 9929,
    "leye": 9448,
    "rear": 616,
    "lear": 6,
    "rthumb": 8079,
    "rindex": 7669,
    "rmiddle": 7794,
    "rring": 7905,
    "rpinky": 8022,
    "lthumb": 5361,
    "lindex": 4933,
    "lmiddle": 5058,
    "lring": 5169,
    "lpinky": 5286,
    "LBigToe": 5770,
    "LSmallToe": 5780,
    "LHeel": 8846,
    "RBigToe": 8463,
    "RSmallToe": 8474,
    "RHeel": 8635,
}
VERTEX_IDS_MANO = {"thumb": 744, "index": 320, "middle": 443, "ring": 554, "pinky": 671}

_EXTRA_ORDER = FACE_KEYPOINTS + FEET_KEYPOINTS + FINGERTIP_KEYPOINTS
EXTRA_JOINTS = tuple(EXTRA_JOINT_NAMES[k] for k in _EXTRA_ORDER)

FACE_LANDMARKS = (
    tuple(f"right_eye_brow{k}" for k in range(1, 6))
    + tuple(f"left_eye_brow{k}" for k in range(5, 0, -1))
    + ("nose1", "nose2", "nose3", "nose4", "right_nose_2", "right_nose_1", "nose_middle", "left_nose_1", "left_nose_2")
    + tuple(f"right_eye{k}" for k in range(1, 7))
    + ("left_eye4", "left_eye3", "left_eye2", "left_eye1", "left_eye6", "left_eye5")
    + (
        "right_mouth_1",
        "right_mouth_2",
        "right_mouth_3",
        "mouth_top",
        "left_mouth_3",
        "left_mouth_2",
        "left_mouth_1",
        "left_mouth_5",
        "left_mouth_4",
        "mouth_bottom",
        "right_mouth_4",
        "right_mouth_5",
        "right_lip_1",
        "right_lip_2",
        "lip_top",
        "left_lip_2",
        "left_lip_1",
        "left_lip_3",
        "lip_bottom",
        "right_lip_3",
    )
)
FACE_CONTOUR = (
    tuple(f"right_contour_{k}" for k in range(1, 9))
    + ("contour_middle",)
    + tuple(f"left_contour_{k}" for k in range(8, 0, -1))
)
