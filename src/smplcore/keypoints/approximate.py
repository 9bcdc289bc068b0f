"""Where a convention's point is not the point the vocabulary name means, as data.

Two conventions may use the same name for different points: COCO's hips are annotated on the
body's outline, SMPL's hip joints sit inside the pelvis; OpenPose's ``neck`` is the midpoint of
its shoulders, SMPL's ``neck`` is a joint at the base of the neck. Each row of
:data:`APPROXIMATE` says: in these conventions the point called ``name`` is defined as
``definition`` and only approximates the vocabulary point ``like`` (smplx's definition). A point
not listed is the vocabulary's own point.

:func:`smplcore.keypoints.convert` takes a point across exactly when both sides define it the same
way, approximately (masked with ``exact_only=True``) when both approximate the same ``like``.
:data:`SYNTHESIS` lists the points some conventions define exactly as the midpoint of two others.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Approximation:
    """One row of the approximate-pair table.

    Attributes
    ----------
    conventions : the convention keys in which the point has this definition.
    name : the point's vocabulary name in those conventions.
    like : the vocabulary (smplx) point it approximates (may equal ``name``).
    definition : a tag for how those conventions define it; equal tags mean the same point.
    note : what differs, in words.
    """

    conventions: tuple[str, ...]
    name: str
    like: str
    definition: str
    note: str


_COCO_STYLE = ("coco17", "coco_wholebody133", "openpose18", "openpose25", "openpose135", "openpose137")
_OPENPOSE_NECK = ("openpose18", "openpose25", "openpose137")
_HANDS = ("openpose137", "coco_wholebody133")
_PUPILS = ("openpose135", "openpose137", "face70")


def _pair(conventions: tuple[str, ...], names: tuple[str, ...], likes: tuple[str, ...], definition: str, note: str):
    return tuple(Approximation(tuple(conventions), n, lk, definition, note) for n, lk in zip(names, likes, strict=True))


APPROXIMATE: tuple[Approximation, ...] = (
    *_pair(
        _COCO_STYLE,
        ("left_hip", "right_hip"),
        ("left_hip", "right_hip"),
        "coco",
        "COCO-style hips are annotated on the body's outline, lower and wider than SMPL's hip joints inside the pelvis",
    ),
    *_pair(
        _OPENPOSE_NECK,
        ("neck",),
        ("neck",),
        "openpose",
        "OpenPose's neck is the midpoint of its shoulders; SMPL's neck joint sits higher, at the base of the neck",
    ),
    *_pair(
        ("openpose25", "openpose137"),
        ("mid_hip",),
        ("pelvis",),
        "openpose",
        "OpenPose's MidHip is the midpoint of its (COCO-style) hips; SMPL's pelvis joint is higher and further back",
    ),
    *_pair(
        ("openpose135",),
        ("upper_neck",),
        ("head",),
        "openpose",
        "BODY_135's UpperNeck (top of the neck) is near SMPL's head joint at the base of the skull",
    ),
    *_pair(
        ("mpii16",),
        ("left_hip", "right_hip", "pelvis"),
        ("left_hip", "right_hip", "pelvis"),
        "mpii",
        "MPII's hips and pelvis are hand-annotated image points, not SMPL's joint centres",
    ),
    *_pair(
        ("mpii16",),
        ("thorax", "upper_neck"),
        ("neck", "head"),
        "mpii",
        "MPII's thorax is at the base of the neck (SMPL's neck joint), its upper neck near SMPL's head joint",
    ),
    *_pair(
        ("h36m17",),
        ("pelvis", "left_hip", "right_hip"),
        ("pelvis", "left_hip", "right_hip"),
        "h36m",
        "Human3.6M's pelvis and hips come from its motion-capture skeleton: the hips sit further out than SMPL's",
    ),
    *_pair(
        ("h36m17",),
        ("spine", "thorax", "neck_nose"),
        ("spine2", "neck", "head"),
        "h36m",
        "Human3.6M's spine (halfway up the back), thorax (base of the neck) and Neck/Nose (chin height) are "
        "near SMPL's spine2, neck and head joints",
    ),
    *_pair(
        ("mediapipe33",),
        ("left_hip", "right_hip"),
        ("left_hip", "right_hip"),
        "mediapipe",
        "MediaPipe's hips are its own (BlazePose) annotation, not SMPL's joint centres",
    ),
    *_pair(
        ("mediapipe33",),
        ("left_eye4", "left_eye1", "right_eye4", "right_eye1", "left_mouth_1", "right_mouth_1"),
        ("left_eye4", "left_eye1", "right_eye4", "right_eye1", "left_mouth_1", "right_mouth_1"),
        "mediapipe",
        "MediaPipe's eye and mouth corners are its own annotation of the points the 68-point face marks",
    ),
    *_pair(
        ("mediapipe33",),
        ("left_pinky1", "right_pinky1", "left_index1", "right_index1", "left_thumb2", "right_thumb2"),
        ("left_pinky1", "right_pinky1", "left_index1", "right_index1", "left_thumb2", "right_thumb2"),
        "mediapipe",
        "MediaPipe's pinky / index / thumb points are knuckles on the hand's outline, SMPL-X's are joint centres",
    ),
    *_pair(
        ("mediapipe33",),
        ("left_big_toe", "right_big_toe"),
        ("left_big_toe", "right_big_toe"),
        "mediapipe",
        "MediaPipe's foot index is the tip of the foot, near but not at the big toe's tip",
    ),
    *(
        row
        for side in ("left", "right")
        for row in _pair(
            _HANDS + (f"hand21_{side}",),
            (f"{side}_wrist_hand",),
            (f"{side}_wrist",),
            "hand",
            "the hand model's own wrist estimate, the same joint as the body's wrist seen by another detector",
        )
    ),
    *_pair(
        _PUPILS,
        ("right_pupil", "left_pupil"),
        ("right_eye", "left_eye"),
        "openpose",
        "OpenPose's pupils are near the eye points of SMPL's surface (a vertex on each eye)",
    ),
)

#: Points defined exactly as the midpoint of two points of the same convention.
SYNTHESIS: dict[tuple[str, str], tuple[str, str]] = {
    **{(c, "neck"): ("left_shoulder", "right_shoulder") for c in _OPENPOSE_NECK},
    **{(c, "mid_hip"): ("left_hip", "right_hip") for c in ("openpose25", "openpose137")},
}

_BY_KEY: dict[tuple[str, str], Approximation] = {(c, row.name): row for row in APPROXIMATE for c in row.conventions}

#: The definition tag of a point no row lists: the vocabulary's (smplx's) own point.
VOCABULARY = "smplx"


def definition(convention: str | None, name: str) -> str:
    """How ``convention`` defines its point ``name`` (``"smplx"`` unless a row of the table says otherwise)."""
    row = _BY_KEY.get((convention, name)) if convention else None
    return VOCABULARY if row is None else row.definition


def like(convention: str | None, name: str) -> str:
    """The vocabulary point that ``convention``'s point ``name`` approximates (``name`` itself if not listed)."""
    row = _BY_KEY.get((convention, name)) if convention else None
    return name if row is None else row.like


def approximation(convention: str, name: str) -> Approximation | None:
    """The table row of ``convention``'s point ``name``, or None when it is the vocabulary's point."""
    return _BY_KEY.get((convention, name))
