"""The keypoint conventions as ordered name tuples, in the published orders, in one vocabulary.

The vocabulary is smplx's joint names wherever the point exists there (``left_shoulder``,
``right_big_toe``, ``left_index1``, ``right_eye_brow1``, ...). Points smplx has no name for get a
plain descriptive one (``mid_hip``, ``head_top``, ``thorax``, ``left_wrist_hand``). How a
convention's *own* spellings (``LShoulder``, ``l_shoulder``, ``Head (H36M)``) map onto the
vocabulary is in :mod:`smplcore.keypoints.aliases`; where a convention's point carries a
vocabulary name but is not quite the same point, :mod:`smplcore.keypoints.approximate` says so.

Sources of the orders (facts, re-typed): OpenPose's ``poseParameters.cpp`` and output docs
(BODY_25, COCO-18, BODY_135, hands 21, face 70), COCO's person keypoints, COCO-WholeBody, MediaPipe
Pose (BlazePose 33), MPII Human Pose, Human3.6M's 17 joints in the order of SPIN's / VIBE's
``J_regressor_h36m`` output, and smplx's ``joint_names.JOINT_NAMES`` for the SMPL family.
"""

from __future__ import annotations

from smplcore.family import names as family

_SIDES = ("left", "right")
_FINGERS = ("thumb", "index", "middle", "ring", "pinky")

COCO17 = (
    "nose",
    "left_eye",
    "right_eye",
    "left_ear",
    "right_ear",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)
FEET6 = ("left_big_toe", "left_small_toe", "left_heel", "right_big_toe", "right_small_toe", "right_heel")

OPENPOSE25 = (
    "nose",
    "neck",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "mid_hip",
    "right_hip",
    "right_knee",
    "right_ankle",
    "left_hip",
    "left_knee",
    "left_ankle",
    "right_eye",
    "left_eye",
    "right_ear",
    "left_ear",
) + FEET6
#: OpenPose's COCO-18 body model (``--model_pose COCO``): BODY_25 without mid-hip and feet.
OPENPOSE18 = tuple(n for n in OPENPOSE25[:19] if n != "mid_hip")


def hand21(side: str) -> tuple[str, ...]:
    """OpenPose / COCO-WholeBody hand order: the wrist, then per finger (thumb ... pinky) 3 joints and the tip.

    The hand's own wrist estimate is ``{side}_wrist_hand`` (the body's wrist keeps ``{side}_wrist``);
    finger joints k = 1, 2, 3 are smplx's ``{side}_{finger}{k}``, the tip is smplx's ``{side}_{finger}``.
    """
    fingers = tuple(name for f in _FINGERS for name in (*(f"{side}_{f}{k}" for k in (1, 2, 3)), f"{side}_{f}"))
    return (f"{side}_wrist_hand",) + fingers


#: The 68 iBUG face points in their published order: jaw contour 0-16, then smplx's 51 landmarks.
FACE68 = family.FACE_CONTOUR + family.FACE_LANDMARKS
#: OpenPose's face output: the 68 points and the two pupils.
FACE70 = FACE68 + ("right_pupil", "left_pupil")

#: OpenPose's experimental BODY_135 model: COCO-17, upper neck, head top, feet, hands without the
#: wrists (20 each), face 70.
OPENPOSE135 = COCO17 + ("upper_neck", "head_top") + FEET6 + hand21("left")[1:] + hand21("right")[1:] + FACE70
#: What an OpenPose JSON from BODY_25 with ``--hand --face`` holds, concatenated in file order:
#: ``pose_keypoints_2d`` (25), ``hand_left_keypoints_2d`` (21), ``hand_right_keypoints_2d`` (21),
#: ``face_keypoints_2d`` (70). (Not ExPose's different 137-point layout.)
OPENPOSE137 = OPENPOSE25 + hand21("left") + hand21("right") + FACE70

COCO_WHOLEBODY133 = COCO17 + FEET6 + FACE68 + hand21("left") + hand21("right")

MEDIAPIPE33 = (
    "nose",
    "left_eye4",  # left eye (inner): the inner corner, iBUG 42
    "left_eye",
    "left_eye1",  # left eye (outer): iBUG 45
    "right_eye4",  # right eye (inner): iBUG 39
    "right_eye",
    "right_eye1",  # right eye (outer): iBUG 36
    "left_ear",
    "right_ear",
    "left_mouth_1",  # mouth (left): the corner, iBUG 54
    "right_mouth_1",  # mouth (right): iBUG 48
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_pinky1",  # left pinky: its first knuckle
    "right_pinky1",
    "left_index1",  # left index: its first knuckle
    "right_index1",
    "left_thumb2",  # left thumb: its second knuckle
    "right_thumb2",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
    "left_heel",
    "right_heel",
    "left_big_toe",  # left foot index: the tip of the foot
    "right_big_toe",
)

MPII16 = (
    "right_ankle",
    "right_knee",
    "right_hip",
    "left_hip",
    "left_knee",
    "left_ankle",
    "pelvis",
    "thorax",
    "upper_neck",
    "head_top",
    "right_wrist",
    "right_elbow",
    "right_shoulder",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
)

#: Human3.6M's 17 joints as SPIN's and VIBE's ``J_regressor_h36m`` outputs them (SPIN's
#: ``H36M_TO_J17`` reads index 1-3 as the left leg, 4-6 as the right leg).
H36M17 = (
    "pelvis",
    "left_hip",
    "left_knee",
    "left_ankle",
    "right_hip",
    "right_knee",
    "right_ankle",
    "spine",
    "thorax",
    "neck_nose",
    "head_top",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
)

MANO_TIPS = tuple(f"hand_{f}" for f in _FINGERS)
#: FLAME's skeleton in the vocabulary: its root (at the base of the neck), its neck joint (where the
#: head turns) and the eyeballs, which are SMPL-X's eyeball joints.
FLAME_SKELETON = ("flame_root", "flame_neck", "jaw", "left_eye_smplhf", "right_eye_smplhf")

CONVENTIONS: dict[str, tuple[str, ...]] = {
    "coco17": COCO17,
    "openpose18": OPENPOSE18,
    "openpose25": OPENPOSE25,
    "openpose135": OPENPOSE135,
    "openpose137": OPENPOSE137,
    "coco_wholebody133": COCO_WHOLEBODY133,
    "mediapipe33": MEDIAPIPE33,
    "mpii16": MPII16,
    "h36m17": H36M17,
    "smpl24": family.SMPL_JOINTS,
    "smpl45": family.SMPL_JOINTS + family.EXTRA_JOINTS,
    "smplh73": family.SMPLH_JOINTS + family.EXTRA_JOINTS,
    "smplx127": family.SMPLX_JOINTS + family.EXTRA_JOINTS + family.FACE_LANDMARKS,
    "smplx144": family.SMPLX_JOINTS + family.EXTRA_JOINTS + family.FACE_LANDMARKS + family.FACE_CONTOUR,
    "mano16": family.MANO_JOINTS,
    "mano21": family.MANO_JOINTS + MANO_TIPS,
    "flame": FLAME_SKELETON + family.FACE_LANDMARKS + family.FACE_CONTOUR,
    "hand21_left": hand21("left"),
    "hand21_right": hand21("right"),
    "face70": FACE70,
}

#: Other spellings accepted for the convention names themselves.
CONVENTION_ALIASES = {
    "coco": "coco17",
    "body25": "openpose25",
    "body_25": "openpose25",
    "openpose": "openpose25",
    "body135": "openpose135",
    "body_135": "openpose135",
    "coco_wholebody": "coco_wholebody133",
    "wholebody": "coco_wholebody133",
    "mediapipe": "mediapipe33",
    "blazepose": "mediapipe33",
    "mpii": "mpii16",
    "h36m": "h36m17",
    "human36m": "h36m17",
    "smpl": "smpl45",
    "smplh": "smplh73",
    "smplx": "smplx144",
    "mano": "mano16",
    "flame73": "flame",
}


def convention_key(convention: str) -> str:
    """The canonical key of ``convention`` (case-insensitive, ``-``/``+``/space tolerant)."""
    if not isinstance(convention, str):
        raise TypeError(f"convention: expected a convention name (str), got {type(convention).__name__}")
    key = convention.strip().lower().replace("-", "_").replace(" ", "_").replace("+", "")
    key = CONVENTION_ALIASES.get(key, key)
    if key not in CONVENTIONS:
        raise ValueError(
            f"convention: unknown keypoint convention {convention!r}; expected one of {sorted(CONVENTIONS)}"
        )
    return key


def names(convention: str) -> tuple[str, ...]:
    """The ordered point names of ``convention`` in the shared vocabulary.

    Parameters
    ----------
    convention : ``coco17``, ``openpose25``, ``openpose135``, ``h36m17``, ``smplx144``, ... (see
        :data:`CONVENTIONS`; aliases such as ``"BODY_25"`` or ``"h36m"`` are accepted).

    Returns
    -------
    tuple of K str, in the convention's published order.
    """
    return CONVENTIONS[convention_key(convention)]


def conventions() -> tuple[str, ...]:
    """The keys of all known conventions."""
    return tuple(CONVENTIONS)
