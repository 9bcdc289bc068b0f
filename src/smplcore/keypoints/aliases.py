"""The conventions' own spellings of their points, mapped onto the shared vocabulary.

:data:`OWN_NAMES` gives, for the conventions that publish their own names, those names in order
(``names(convention)[i]`` is the vocabulary name of ``OWN_NAMES[convention][i]``). :func:`canonical`
turns any accepted spelling into the vocabulary name: first the convention's own table (where a
spelling such as H36M's ``Head`` means the top of the head, not smplx's ``head`` joint), then the
global :data:`ALIASES` (``LShoulder``, ``l_shoulder``, ``OP LShoulder``, smplx's vertex keys
``leye`` / ``LBigToe`` / ``lthumb``), then the vocabulary itself.
"""

from __future__ import annotations

from collections.abc import Iterable

from smplcore.family import names as family
from smplcore.keypoints import conventions as conv

OWN_NAMES: dict[str, tuple[str, ...]] = {
    "openpose25": (
        "Nose",
        "Neck",
        "RShoulder",
        "RElbow",
        "RWrist",
        "LShoulder",
        "LElbow",
        "LWrist",
        "MidHip",
        "RHip",
        "RKnee",
        "RAnkle",
        "LHip",
        "LKnee",
        "LAnkle",
        "REye",
        "LEye",
        "REar",
        "LEar",
        "LBigToe",
        "LSmallToe",
        "LHeel",
        "RBigToe",
        "RSmallToe",
        "RHeel",
    ),
    "mpii16": (
        "r_ankle",
        "r_knee",
        "r_hip",
        "l_hip",
        "l_knee",
        "l_ankle",
        "pelvis",
        "thorax",
        "upper_neck",
        "head_top",
        "r_wrist",
        "r_elbow",
        "r_shoulder",
        "l_shoulder",
        "l_elbow",
        "l_wrist",
    ),
    "h36m17": (
        "Hip",
        "LHip",
        "LKnee",
        "LFoot",
        "RHip",
        "RKnee",
        "RFoot",
        "Spine",
        "Thorax",
        "Neck/Nose",
        "Head",
        "LShoulder",
        "LElbow",
        "LWrist",
        "RShoulder",
        "RElbow",
        "RWrist",
    ),
    "mediapipe33": (
        "nose",
        "left_eye_inner",
        "left_eye",
        "left_eye_outer",
        "right_eye_inner",
        "right_eye",
        "right_eye_outer",
        "left_ear",
        "right_ear",
        "mouth_left",
        "mouth_right",
        "left_shoulder",
        "right_shoulder",
        "left_elbow",
        "right_elbow",
        "left_wrist",
        "right_wrist",
        "left_pinky",
        "right_pinky",
        "left_index",
        "right_index",
        "left_thumb",
        "right_thumb",
        "left_hip",
        "right_hip",
        "left_knee",
        "right_knee",
        "left_ankle",
        "right_ankle",
        "left_heel",
        "right_heel",
        "left_foot_index",
        "right_foot_index",
    ),
    "coco17": conv.COCO17,
}
OWN_NAMES["openpose18"] = tuple(n for n in OWN_NAMES["openpose25"][:19] if n != "MidHip")
#: SPIN's / VIBE's spellings of the H36M points (``Head (H36M)`` is VIBE's name of index 9).
_H36M_EXTRA = {
    "hip": "pelvis",
    "lhip": "left_hip",
    "rhip": "right_hip",
    "lhip (h36m)": "left_hip",
    "rhip (h36m)": "right_hip",
    "lknee": "left_knee",
    "rknee": "right_knee",
    "lankle": "left_ankle",
    "rankle": "right_ankle",
    "spine (h36m)": "spine",
    "neck": "thorax",
    "jaw (h36m)": "neck_nose",
    "head (h36m)": "neck_nose",
    "headtop": "head_top",
    "lshoulder": "left_shoulder",
    "rshoulder": "right_shoulder",
    "lelbow": "left_elbow",
    "relbow": "right_elbow",
    "lwrist": "left_wrist",
    "rwrist": "right_wrist",
}
_FLAME_OWN = {
    "global": "flame_root",
    "neck": "flame_neck",
    "left_eye": "left_eye_smplhf",
    "right_eye": "right_eye_smplhf",
}


def _convention_table(key: str) -> dict[str, str]:
    own = OWN_NAMES.get(key)
    table = {} if own is None else {o.lower(): v for o, v in zip(own, conv.CONVENTIONS[key], strict=True)}
    if key == "h36m17":
        table.update(_H36M_EXTRA)
    if key == "flame":
        table.update(_FLAME_OWN)
    return table


#: Per convention: lower-cased own spelling -> vocabulary name.
CONVENTION_SPELLINGS: dict[str, dict[str, str]] = {key: _convention_table(key) for key in conv.CONVENTIONS}
#: Spellings that look like a vocabulary name but mean another point in that convention.
FALSE_FRIENDS: dict[tuple[str, str], str] = {
    ("h36m17", "Head"): "the top of the head (head_top), not smplx's 'head' joint at the base of the skull",
    ("h36m17", "neck"): "VIBE's name of H36M's thorax, not smplx's 'neck' joint",
    ("mediapipe33", "left_pinky"): "the first knuckle (left_pinky1), not smplx's fingertip 'left_pinky'",
    ("mediapipe33", "left_index"): "the first knuckle (left_index1), not smplx's fingertip 'left_index'",
    ("mediapipe33", "left_thumb"): "the second knuckle (left_thumb2), not smplx's fingertip 'left_thumb'",
    ("flame", "left_eye"): "FLAME's eyeball joint (left_eye_smplhf), not smplx's eye vertex 'left_eye'",
    ("flame", "neck"): "FLAME's neck joint (flame_neck), where the head turns, not smplx's 'neck'",
}


def _global_aliases() -> dict[str, str]:
    out: dict[str, str] = {}
    vocabulary = {n for names in conv.CONVENTIONS.values() for n in names}
    # OpenPose's camel case with an L/R prefix, also with SPIN's "OP " prefix.
    for own, vocab in zip(OWN_NAMES["openpose25"], conv.OPENPOSE25, strict=True):
        out[own.lower()] = vocab
        out[f"op {own.lower()}"] = vocab
    out["upperneck"] = "upper_neck"
    out["headtop"] = "head_top"
    # MPII's l_/r_ prefixes and the "left hip" / "Left Hip" spellings of any vocabulary name.
    for name in vocabulary:
        for side, short in (("left_", "l_"), ("right_", "r_")):
            if name.startswith(side):
                rest = name[len(side) :]
                out.setdefault(short + rest, name)
                out.setdefault(short[0] + rest, name)  # lknee, rshoulder
        out.setdefault(name.replace("_", " "), name)
    # smplx's vertex-id keys (nose, leye, LBigToe, lthumb, ...).
    for key, name in family.EXTRA_JOINT_NAMES.items():
        out.setdefault(key.lower(), name)
    for key, name in (("pelvis (mpii)", "pelvis"), ("thorax (mpii)", "thorax"), ("top of head (lsp)", "head_top")):
        out[key] = name
    return {k: v for k, v in out.items() if k not in vocabulary}


#: Global spellings (lower-cased) -> vocabulary name; a convention's own table wins over these.
ALIASES: dict[str, str] = _global_aliases()
_VOCABULARY = frozenset(n for names in conv.CONVENTIONS.values() for n in names)


def canonical(name: str, convention: str | None = None) -> str:
    """The vocabulary name of ``name``, a spelling of a point (in ``convention`` if given).

    Unknown spellings are returned unchanged (lower-cased and with spaces as underscores only when
    that makes them a vocabulary name), so custom point names pass through.
    """
    if not isinstance(name, str):
        raise TypeError(f"point name: expected str, got {type(name).__name__}")
    low = name.strip().lower()
    if convention is not None:
        table = CONVENTION_SPELLINGS[conv.convention_key(convention)]
        if low in table:
            return table[low]
    if name in _VOCABULARY:
        return name
    if low in _VOCABULARY:
        return low
    if low in ALIASES:
        return ALIASES[low]
    snake = low.replace(" ", "_").replace("-", "_")
    return snake if snake in _VOCABULARY else name


def canonical_names(names: Iterable[str], convention: str | None = None) -> tuple[str, ...]:
    """:func:`canonical` over a sequence of names."""
    return tuple(canonical(n, convention) for n in names)


def own_names(convention: str) -> tuple[str, ...]:
    """The convention's own published spellings, in order (the vocabulary names where it has none)."""
    key = conv.convention_key(convention)
    return OWN_NAMES.get(key, conv.CONVENTIONS[key])
