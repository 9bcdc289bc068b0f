"""The VRM 1.0 humanoid of a body model: the bone map from our joint names (:data:`HUMAN_BONES`), the
``meta`` with the model's licence (:func:`default_meta`) and the VRM T-pose rest (:func:`vrm_tpose`), used by
:mod:`smplcore.export.vrm` for avatars and clips.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["HUMAN_BONES", "REQUIRED_BONES", "VRM_LICENSE_URL", "default_meta", "humanoid_bones", "vrm_tpose"]


VRM_LICENSE_URL = "https://vrm.dev/licenses/1.0/"

#: Our joint name -> VRM 1.0 humanoid bone name.
HUMAN_BONES: dict[str, str] = {
    "pelvis": "hips",
    "spine1": "spine",
    "spine2": "chest",
    "spine3": "upperChest",
    "neck": "neck",
    "head": "head",
    "jaw": "jaw",
    "left_eye_smplhf": "leftEye",
    "right_eye_smplhf": "rightEye",
}
for _side, _vrm in (("left", "left"), ("right", "right")):
    HUMAN_BONES.update(
        {
            f"{_side}_hip": f"{_vrm}UpperLeg",
            f"{_side}_knee": f"{_vrm}LowerLeg",
            f"{_side}_ankle": f"{_vrm}Foot",
            f"{_side}_foot": f"{_vrm}Toes",
            f"{_side}_collar": f"{_vrm}Shoulder",
            f"{_side}_shoulder": f"{_vrm}UpperArm",
            f"{_side}_elbow": f"{_vrm}LowerArm",
            f"{_side}_wrist": f"{_vrm}Hand",
            f"{_side}_thumb1": f"{_vrm}ThumbMetacarpal",
            f"{_side}_thumb2": f"{_vrm}ThumbProximal",
            f"{_side}_thumb3": f"{_vrm}ThumbDistal",
        }
    )
    for _ours, _theirs in (("index", "Index"), ("middle", "Middle"), ("ring", "Ring"), ("pinky", "Little")):
        for _k, _part in ((1, "Proximal"), (2, "Intermediate"), (3, "Distal")):
            HUMAN_BONES[f"{_side}_{_ours}{_k}"] = f"{_vrm}{_theirs}{_part}"

#: The bones every VRM 1.0 humanoid has.
REQUIRED_BONES = (
    "hips",
    "spine",
    "head",
    *(f"{s}{b}" for s in ("left", "right") for b in ("UpperLeg", "LowerLeg", "Foot", "UpperArm", "LowerArm", "Hand")),
)
#: Humanoid bones a VRM animation must not animate (look-at drives them).
_LOOK_AT_BONES = ("leftEye", "rightEye")

_LICENSES = {
    "open": ("https://creativecommons.org/publicdomain/zero/1.0/", "smplcore's open body model, CC0 1.0"),
    "smpl": ("https://smpl.is.tue.mpg.de/modellicense.html", "SMPL"),
    "smplh": ("https://mano.is.tue.mpg.de/license.html", "SMPL+H (MANO)"),
    "smplx": ("https://smpl-x.is.tue.mpg.de/modellicense.html", "SMPL-X"),
}


def humanoid_bones(joint_names: list[str] | tuple[str, ...]) -> dict[str, int]:
    """VRM humanoid bone name -> joint index for a skeleton with ``joint_names``.

    Raises
    ------
    ValueError : when a required VRM bone has no joint (MANO and FLAME have no body).
    """
    bones = {HUMAN_BONES[n]: j for j, n in enumerate(joint_names) if n in HUMAN_BONES}
    missing = [b for b in REQUIRED_BONES if b not in bones]
    if missing:
        raise ValueError(
            f"model: a VRM humanoid needs the bones {missing}, which a skeleton of {list(joint_names)[:6]}... lacks"
        )
    return bones


def default_meta(model: Any) -> dict[str, Any]:
    """``VRMC_vrm.meta`` for ``model``: the open model is CC0 (anyone may use, modify and redistribute the
    avatar); an official SMPL-family file is under the licence its user accepted, so the avatar is marked
    personal, non-profit, not redistributable and not modifiable, pointing at that licence
    (``otherLicenseUrl``). Override any field with ``save_vrm(..., meta={...})``."""
    kind = model.rig.model_type
    url, title = _LICENSES.get(kind, ("", kind))
    meta: dict[str, Any] = {
        "name": f"{kind} body",
        "version": "1",
        "authors": ["smplcore"],
        "licenseUrl": VRM_LICENSE_URL,
    }
    if kind == "open":
        meta.update(
            avatarPermission="everyone",
            allowExcessivelyViolentUsage=True,
            allowExcessivelySexualUsage=True,
            commercialUsage="corporation",
            allowPoliticalOrReligiousUsage=True,
            allowAntisocialOrHateUsage=True,
            creditNotation="unnecessary",
            allowRedistribution=True,
            modification="allowModificationRedistribution",
            otherLicenseUrl=url,
            copyrightInformation="No rights reserved (CC0 1.0 Universal).",
            thirdPartyLicenses=f"Body: {title} (public domain dedication).",
        )
    else:
        meta.update(
            avatarPermission="onlySeparatelyLicensedPerson",
            commercialUsage="personalNonProfit",
            creditNotation="required",
            allowRedistribution=False,
            modification="prohibited",
            thirdPartyLicenses=(
                f"Body: the {title} model ({model.rig.source}), used under the licence its user accepted"
                + (f" ({url})" if url else "")
                + ". This avatar is derived from it and subject to the same terms; it grants no further rights."
            ),
        )
        if url:
            meta["otherLicenseUrl"] = url
    return meta


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit direction ``a`` to unit direction ``b`` (3, 3)."""
    axis = np.cross(a, b)
    s, c = float(np.linalg.norm(axis)), float(np.dot(a, b))
    if s < 1e-12 and c < 0:
        raise ValueError("vrm_tpose: a bone points opposite to its T-pose direction")
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + k + k @ k / (1.0 + c)  # (1 - c) / s^2 = 1 / (1 + c), stable for small angles


def _alignments(names: list[str]) -> dict[int, tuple[int, np.ndarray]]:
    """Joint -> (the child whose direction is aligned, the T-pose direction) for arms, hands and fingers."""
    index = {n: j for j, n in enumerate(names)}
    out: dict[int, tuple[int, np.ndarray]] = {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        along = np.array([sign, 0.0, 0.0])
        thumb = np.array([sign, 0.0, 1.0]) / np.sqrt(2.0)
        hand_child = next((f"{side}_{c}" for c in ("middle1", "hand") if f"{side}_{c}" in index), None)
        chain = [(f"{side}_shoulder", f"{side}_elbow", along), (f"{side}_elbow", f"{side}_wrist", along)]
        if hand_child is not None:
            chain.append((f"{side}_wrist", hand_child, along))
        for finger in ("index", "middle", "ring", "pinky"):
            chain += [(f"{side}_{finger}{k}", f"{side}_{finger}{k + 1}", along) for k in (1, 2)]
        chain += [(f"{side}_thumb{k}", f"{side}_thumb{k + 1}", thumb) for k in (1, 2)]
        for joint, child, direction in chain:
            if joint in index and child in index:
                out[index[joint]] = (index[child], direction)
    return out


def vrm_tpose(
    rest_joints: np.ndarray, parents: np.ndarray, joint_names: list[str] | tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """The VRM T-pose of a skeleton in SMPL's rest pose.

    Parameters
    ----------
    rest_joints : (J, 3) rest joint positions.
    parents : (J,) parent of each joint, -1 for the root (parents before children).
    joint_names : the J joint names.

    Returns
    -------
    rotations : (J, 3, 3) world rotation ``C_j`` of each joint taking SMPL's rest to the T-pose
        (the identity except on arms, hands and fingers).
    joints : (J, 3) joint positions in the T-pose.
    """
    rest = np.asarray(rest_joints, dtype=np.float64)
    parents = np.asarray(parents)
    if np.any(parents[1:] >= np.arange(1, len(parents))):
        raise ValueError("parents: expected every joint after its parent")
    targets = _alignments(list(joint_names))
    world = np.tile(np.eye(3), (len(rest), 1, 1))
    pos = rest.copy()
    for j in range(len(rest)):
        p = int(parents[j])
        rot = world[p] if p >= 0 else np.eye(3)
        if p >= 0:
            pos[j] = pos[p] + world[p] @ (rest[j] - rest[p])
        if j in targets:
            child, direction = targets[j]
            bone = rot @ (rest[child] - rest[j])
            rot = _swing(bone / np.linalg.norm(bone), direction) @ rot
        world[j] = rot
    return world, pos
