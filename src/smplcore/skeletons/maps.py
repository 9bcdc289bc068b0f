"""The named skeleton maps, and finding the map of a skeleton from its joint names or point count.

BVH skeletons. Each choice was measured with ``python tools/measure_skeleton_maps.py``: fit_joints on the open
model (no joint limits), shared betas, 120 frames per clip; joint error, the spine's bend (spine1-3 x, forward
positive) and the rotation of spine3, against the alternatives (numbers: clip A / clip B):

* ``cmu_daz``: cgspeed's Daz-friendly CMU release (43 joints, cm). The Daz shoulder joint sits 5.6 cm inside
  and 5 cm behind the model's: moved out and forward in the collar's frame (02_01 / 135_03: 11.1 / 9.4 mm,
  spine3 17 / 6°, spine outside its limits in 1 / 8 % of frames). Unmoved, or blended towards the elbow, the
  chest arches back (spine3 90 / 96° and 76 / 77°, 100 %). The spine joints (abdomen, chest) pinned: 86° on
  135_03; the head added: the neck turns 15° back. The root, collars, buttocks, fingers and eyes are dropped.
* ``cmu_mb``: cgspeed's MotionBuilder-friendly 2010 release (31 joints, CMU ASF units). The model's neck on the
  CMU ``Head`` joint (06_01 / 05_10: 11.5 / 18.9 mm, spine3 21 / 27°; the dance clip's spine leaves its limits
  in 86 % of frames with or without the map); on ``Neck1`` the spine folds (spine3 68 / 59°), with every spine
  joint pinned (Hips, Spine, Spine1, Neck1, Head) it folds and twists (spine3 90 / 102°, error 22.6 / 27.0 mm).
  CMU's torso (hip joints to shoulders 36 cm) is shorter than the model's (46 cm): see
  :func:`smplcore.skeletons.diagnostics.bone_lengths`. The wrist on ``HandIndex1`` (the end of CMU's short
  radius, ``Hand``, gives 14.7 / 23.5 mm).
* ``cmu_max``: cgspeed's 3dsMax-friendly release (31 joints, CMU ASF units): as MotionBuilder's (131_02: 8.4 mm,
  spine3 25°; the neck on ``Neck``: 65°; the wrist on ``LeftWrist``: 10.8 mm).
* ``smpl``: the SMPL family's own 22 body joints, as ``smplcore export`` writes a BVH (every joint, weight 1).
* ``fair``: the AnimatedDrawings fair1 capture (27 joints, Z up, undocumented units: scaled to a 0.8 m leg).
  Limbs, neck, and the head moved 5 cm forward at a quarter weight (jumping / zombie: 10.7 / 9.4 mm, spine3
  18 / 15°); pinning Spine3 and the clavicles twists the chest (spine3 49° on jumping). ``wave_hello`` has other
  proportions (thigh 11.5 units, shin 8.8: 35 mm whatever the map).

3D keypoint skeletons (the point names and orders are :mod:`smplcore.keypoints`' conventions; not measured on
real captures, which the shared data lacks: hips, which each convention annotates its own way, and the head
points are down-weighted, points the model lacks are dropped):

* ``h36m17``: Human3.6M's 17 joints (in :func:`smplcore.keypoints.names` ``"h36m17"`` order), ``h36m32``: its
  32-joint motion-capture skeleton (the metadata's order: 1-5 the right leg, 6-10 the left);
* ``mediapipe33``: MediaPipe Pose world landmarks (metres, origin between the hips, y down);
* ``openpose25``: OpenPose BODY_25 triangulated to 3D.
"""

from __future__ import annotations

from smplcore import keypoints
from smplcore.family import names as family
from smplcore.skeletons.mapping import SkeletonMap, Target, drop_rest, lr, sided

# ---------------------------------------------------------------------------------------------------- BVH maps

DAZ_JOINTS = (
    "hip", "abdomen", "chest", "neck", "head", "leftEye", "rightEye",
    *(f"{s}{j}" for s in "rl" for j in ("Collar", "Shldr", "ForeArm", "Hand", "Thumb1", "Thumb2", "Index1", "Index2",
                                          "Mid1", "Mid2", "Ring1", "Ring2", "Pinky1", "Pinky2")),
    *(f"{s}{j}" for s in "rl" for j in ("Buttock", "Thigh", "Shin", "Foot")),
    "lFoot_end", "rFoot_end",  # the feet's End Sites (no toe joints): the ball of the foot
)  # fmt: skip
MB_JOINTS = (
    "Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RHipJoint", "RightUpLeg", "RightLeg",
    "RightFoot", "RightToeBase", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head", "LeftShoulder", "LeftArm",
    "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb", "RightShoulder", "RightArm",
    "RightForeArm", "RightHand", "RightFingerBase", "RightHandIndex1", "RThumb",
)  # fmt: skip
MAX_JOINTS = (
    "Hips", "LHipJoint", "LeftHip", "LeftKnee", "LeftAnkle", "LeftToe", "RHipJoint", "RightHip", "RightKnee",
    "RightAnkle", "RightToe", "lowerback", "Chest", "Chest2", "lowerneck", "Neck", "Head", "LeftCollar",
    "LeftShoulder", "LeftElbow", "LeftWrist", "lhand", "LFingers", "LThumb", "RightCollar", "RightShoulder",
    "RightElbow", "RightWrist", "rhand", "RFingers", "RThumb",
)  # fmt: skip
FAIR_JOINTS = (
    "Hips", "Spine", "Spine1", "Spine2", "Spine3", "Neck", "Head", "RightShoulder", "RightArm", "RightForeArm",
    "RightHand", "RightHandEnd", "RightHandThumb1", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "LeftHandEnd", "LeftHandThumb1", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase", "LeftUpLeg", "LeftLeg",
    "LeftFoot", "LeftToeBase",
)  # fmt: skip


def _cmu_daz() -> SkeletonMap:
    targets = (
        *sided("hip", *lr("{s}Thigh")),
        *sided("knee", *lr("{s}Shin")),
        *sided("ankle", *lr("{s}Foot")),
        *sided("foot", *lr("{s}Foot_end")),
        # Daz's shoulder joint sits 5.6 cm inside and 5 cm behind the model's: moved out and forward in the
        # collar's frame (a blend towards the elbow instead goes down with a hanging arm and arches the chest back)
        *sided("shoulder", *lr("{s}Shldr"), offset=(0.056, 0.0, 0.03)),
        *sided("elbow", *lr("{s}ForeArm")),
        *sided("wrist", *lr("{s}Hand")),
        Target("neck", ("neck",)),
    )
    reasons = {
        "hip": "the root sits 2.6 cm below the hip joints and 4 cm below the model's pelvis: the hips place it",
        "abdomen": "spine joints: the Daz skeleton's spine points do not match the model's spine joints (measured)",
        "chest": "spine joints: see abdomen",
        "lCollar": "the collar joint, 7 cm behind the model's",
        "rCollar": "the collar joint, 7 cm behind the model's",
        "lButtock": "a Daz helper joint (constant channels)",
        "rButtock": "a Daz helper joint (constant channels)",
    }
    dropped = drop_rest(DAZ_JOINTS, targets, reasons, "fingers and eyes: constant channels in the Daz release")
    return SkeletonMap("cmu_daz", "cgspeed CMU BVH, Daz-friendly (43 joints)", "bvh", DAZ_JOINTS, targets, dropped,
                       "y", "cm", ("daz", "cmu_daz43"))  # fmt: skip


def _cmu_mb() -> SkeletonMap:
    targets = (
        *sided("hip", *lr("{S}UpLeg")),
        *sided("knee", *lr("{S}Leg")),
        *sided("ankle", *lr("{S}Foot")),
        *sided("foot", *lr("{S}ToeBase")),
        *sided("shoulder", *lr("{S}Arm")),
        *sided("elbow", *lr("{S}ForeArm")),
        *sided("wrist", *lr("{S}HandIndex1")),
        Target("neck", ("Head",)),
    )
    reasons = {
        "Hips": "the root sits 9-11 cm above the hip joints (the open model's pelvis 1.3 cm): the hips place it",
        "Neck1": "mid-neck; mapping the model's neck here folds the spine (the CMU torso is too short for the model)",
        "Spine": "spine joints of a torso shorter than the model's: pinning them folds the spine",
        "Spine1": "spine joints of a torso shorter than the model's: pinning them folds the spine",
        "LeftHand": "the end of CMU's short radius; the model's wrist fits LeftHandIndex1 better (measured)",
        "RightHand": "the end of CMU's short radius; the model's wrist fits RightHandIndex1 better (measured)",
    }
    dropped = drop_rest(MB_JOINTS, targets, reasons, "zero-length or constant joints (helpers, fingers)")
    return SkeletonMap("cmu_mb", "cgspeed CMU BVH, MotionBuilder-friendly 2010 (31 joints)", "bvh", MB_JOINTS,
                       targets, dropped, "y", "cmu", ("mb", "cmu_mb31", "motionbuilder"))  # fmt: skip


def _cmu_max() -> SkeletonMap:
    targets = (
        *sided("hip", *lr("{S}Hip")),
        *sided("knee", *lr("{S}Knee")),
        *sided("ankle", *lr("{S}Ankle")),
        *sided("foot", *lr("{S}Toe")),
        *sided("shoulder", *lr("{S}Shoulder")),
        *sided("elbow", *lr("{S}Elbow")),
        *sided("wrist", *lr("{L}Fingers")),
        Target("neck", ("Head",)),
    )
    reasons = {
        "Hips": "the root sits 9 cm above the hip joints: the hips place the model's pelvis",
        "Neck": "mid-neck; mapping the model's neck here folds the spine (the CMU torso is too short for the model)",
        "Chest": "spine joints of a torso shorter than the model's: pinning them folds the spine",
        "Chest2": "spine joints of a torso shorter than the model's: pinning them folds the spine",
        "LeftWrist": "the end of CMU's short radius; the model's wrist fits LFingers better (measured)",
        "RightWrist": "the end of CMU's short radius; the model's wrist fits RFingers better (measured)",
    }
    dropped = drop_rest(MAX_JOINTS, targets, reasons, "zero-length or constant joints (helpers, fingers)")
    return SkeletonMap("cmu_max", "cgspeed CMU BVH, 3dsMax-friendly (31 joints)", "bvh", MAX_JOINTS, targets,
                       dropped, "y", "cmu", ("max", "cmu_max31", "3dsmax"))  # fmt: skip


def _fair() -> SkeletonMap:
    targets = (
        *sided("hip", *lr("{S}UpLeg")),
        *sided("knee", *lr("{S}Leg")),
        *sided("ankle", *lr("{S}Foot")),
        *sided("foot", *lr("{S}ToeBase")),
        *sided("shoulder", *lr("{S}Arm")),
        *sided("elbow", *lr("{S}ForeArm")),
        *sided("wrist", *lr("{S}Hand")),
        Target("neck", ("Neck",)),
        # FAIR's head joint sits 5 cm behind and 2 cm above the model's: moved in the neck's frame
        Target("head", ("Head",), offset=(0.0, -0.02, 0.05), weight=0.25),
    )
    reasons = {
        "Hips": "the root, 2.5 cm above the hip joints: the hips place the model's pelvis",
        "Spine3": "pinned, it twists and bends the model's upper spine (measured): the prior places the spine",
        "LeftShoulder": "the clavicle joint: pinned, it twists the chest (measured)",
        "RightShoulder": "the clavicle joint: pinned, it twists the chest (measured)",
    }
    dropped = drop_rest(FAIR_JOINTS, targets, reasons, "no model joint there (lower spine, hand ends, thumbs)")
    return SkeletonMap("fair", "AnimatedDrawings fair1 capture (27 joints, Z up)", "bvh", FAIR_JOINTS, targets,
                       dropped, "z", None, ("fair27", "animateddrawings"))  # fmt: skip


def _smpl() -> SkeletonMap:
    """The SMPL family's own skeleton, as ``smplcore export`` writes it to BVH (joints named after the model's)."""
    targets = tuple(Target(n, (n,)) for n in family.SMPL_BODY)
    return SkeletonMap("smpl", "the SMPL family's skeleton (smplcore's BVH export)", "bvh", family.SMPL_BODY,
                       targets, (), "y", "m", ("smplcore", "smpl22"))  # fmt: skip


# ------------------------------------------------------------------------------------------------ keypoint maps

H36M32 = (
    "Hips", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase", "RightToeBase_end", "LeftUpLeg", "LeftLeg",
    "LeftFoot", "LeftToeBase", "LeftToeBase_end", "Spine", "Spine1", "Neck", "Head", "Head_end", "LeftShoulder",
    "LeftArm", "LeftForeArm", "LeftHand", "LeftHandThumb", "LeftHandThumb_end", "L_Wrist_End", "L_Wrist_End_end",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightHandThumb", "RightHandThumb_end", "R_Wrist_End",
    "R_Wrist_End_end",
)  # fmt: skip
"""Human3.6M's 32 motion-capture joints in its metadata's order (End Sites named ``<joint>_end``); rows
0, 1, 2, 3, 6, 7, 8, 12, 13, 14, 15, 17, 18, 19, 25, 26, 27 are the usual 17 (VideoPose3D's order)."""


def _h36m17() -> SkeletonMap:
    names = keypoints.names("h36m17")
    targets = (
        *(Target(n, (n,)) for n in names if n.endswith(("_knee", "_ankle", "_shoulder", "_elbow", "_wrist"))),
        *sided("hip", *lr("{x}_hip"), weight=0.5),
        Target("neck", ("thorax",), weight=0.5),
        Target("head", ("neck_nose",), weight=0.25),
    )
    reasons = {
        "pelvis": "Human3.6M's root is the midpoint of its hips, below the model's pelvis: the hips place it",
        "spine": "halfway up the back, between the model's spine joints",
        "head_top": "the top of the head: no model joint there",
    }
    return SkeletonMap("h36m17", "Human3.6M, 17 joints (3D)", "points", names, targets,
                       drop_rest(names, targets, reasons, ""), "z", "mm", ("h36m", "human36m"))  # fmt: skip


def _h36m32() -> SkeletonMap:
    targets = (
        *sided("hip", *lr("{S}UpLeg"), weight=0.5),
        *sided("knee", *lr("{S}Leg")),
        *sided("ankle", *lr("{S}Foot")),
        *sided("foot", *lr("{S}ToeBase"), weight=0.5),
        *sided("shoulder", *lr("{S}Arm")),
        *sided("elbow", *lr("{S}ForeArm")),
        *sided("wrist", *lr("{S}Hand")),
        Target("neck", ("Neck",), weight=0.5),
        Target("head", ("Head",), weight=0.25),
    )
    reasons = {
        "Hips": "the root, the midpoint of the hips: the hips place the model's pelvis",
        "Head_end": "the top of the head: no model joint there",
    }
    return SkeletonMap("h36m32", "Human3.6M motion-capture skeleton, 32 joints (3D)", "points", H36M32, targets,
                       drop_rest(H36M32, targets, reasons, "a duplicate or an end point"), "z", "mm")  # fmt: skip


def _mediapipe33() -> SkeletonMap:
    names = keypoints.names("mediapipe33")
    exact = ("_shoulder", "_elbow", "_wrist", "_knee", "_ankle", "_heel")
    targets = (
        *(Target(n, (n,)) for n in names if n.endswith(exact)),
        *sided("hip", *lr("{x}_hip"), weight=0.5),
        *sided("big_toe", *lr("{x}_big_toe"), weight=0.5),
        *sided("hand", *zip(lr("{x}_index1"), lr("{x}_pinky1")), weight=0.5),
        *(Target(n, (n,), weight=0.25) for n in ("nose", "left_eye", "right_eye", "left_ear", "right_ear")),
    )
    reasons = {n: "thumb knuckle: no model joint there" for n in ("left_thumb2", "right_thumb2")}
    dropped = drop_rest(names, targets, reasons, "eye and mouth corners: no model joint there")
    return SkeletonMap("mediapipe33", "MediaPipe Pose world landmarks (33)", "points", names, targets, dropped,
                       "-y", "m", ("mediapipe", "blazepose"))  # fmt: skip


def _openpose25() -> SkeletonMap:
    names = keypoints.names("openpose25")
    exact = ("_shoulder", "_elbow", "_wrist", "_knee", "_ankle", "_heel", "_big_toe", "_small_toe")
    targets = (
        *(Target(n, (n,)) for n in names if n.endswith(exact)),
        *sided("hip", *lr("{x}_hip"), weight=0.5),
        *(Target(n, (n,), weight=0.25) for n in ("nose", "left_eye", "right_eye", "left_ear", "right_ear")),
    )
    reasons = {
        "neck": "OpenPose's neck is the midpoint of its shoulders, below the model's neck",
        "mid_hip": "the midpoint of OpenPose's hips: the hips place the model's pelvis",
    }
    return SkeletonMap("openpose25", "OpenPose BODY_25 (3D)", "points", names, targets,
                       drop_rest(names, targets, reasons, ""), "-y", "mm", ("body25", "openpose"))  # fmt: skip


# ------------------------------------------------------------------------------------------------ the registry

MAPS: dict[str, SkeletonMap] = {
    m.name: m
    for m in (_cmu_daz(), _cmu_mb(), _cmu_max(), _fair(), _smpl(), _h36m17(), _h36m32(), _mediapipe33(), _openpose25())
}


def skeleton_names() -> tuple[str, ...]:
    """The names of the known skeleton maps."""
    return tuple(MAPS)


def skeleton_map(name: str | SkeletonMap) -> SkeletonMap:
    """The map called ``name`` (case-insensitive; aliases such as ``"mb"``, ``"daz"``, ``"h36m"`` too)."""
    if isinstance(name, SkeletonMap):
        return name
    key = str(name).strip().lower().replace("-", "_")
    for m in MAPS.values():
        if key == m.name or key in m.aliases:
            return m
    raise ValueError(f"skeleton: unknown skeleton {name!r}; known: {', '.join(MAPS)}")


def detect_skeleton(joint_names: tuple[str, ...] | list[str]) -> SkeletonMap:
    """The BVH skeleton map whose points are those of ``joint_names`` (a clip's ``point_names``: its joints and
    End Sites; all the map's points present, the closest set wins), or a ValueError naming the known skeletons."""
    have = set(joint_names)
    best, score = None, 0.0
    for m in MAPS.values():
        if m.kind != "bvh" or not set(m.points) <= have:
            continue
        s = len(m.points) / len(have | set(m.points))
        if s > score:
            best, score = m, s
    if best is None:
        shown = ", ".join(list(joint_names)[:8]) + (" ..." if len(joint_names) > 8 else "")
        raise ValueError(
            f"skeleton: no known skeleton has the joints {shown}; known BVH skeletons: "
            f"{', '.join(m.name for m in MAPS.values() if m.kind == 'bvh')} (pass skeleton= / --skeleton)"
        )
    return best


def skeleton_for_points(count: int) -> SkeletonMap:
    """The keypoint skeleton with ``count`` points (17: h36m17, 25: openpose25, 32: h36m32, 33: mediapipe33)."""
    found = [m for m in MAPS.values() if m.kind == "points" and len(m.points) == count]
    if len(found) != 1:
        known = ", ".join(f"{m.name} ({len(m.points)})" for m in MAPS.values() if m.kind == "points")
        raise ValueError(f"skeleton: no keypoint skeleton has {count} points; known: {known} (pass the skeleton)")
    return found[0]
