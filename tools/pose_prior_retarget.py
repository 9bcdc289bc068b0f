"""Retarget a mocap clip (BVH) to the open model's body poses, for tools/train_pose_prior.py.

The CMU skeletons' proportions are not the model's (the cgspeed MotionBuilder torso is ~10 cm shorter from the
hips to the shoulders than any body of the open model's shape space), so fitting the model's joints to the
mocap's joint *positions* bends the spine and collars to close the gap: a prior learned from such fits would
teach folded spines. Here the model's own skeleton (rest joints of the mean shape, betas = 0) is re-posed with
the mocap's motion instead, and ``smplcore.fit.fit_joints`` finds the body pose that reaches it:

* limb bones (hip→knee→ankle, shoulder→elbow→wrist) take the direction of the mocap's bone, at the model's
  length (the rest poses' limb directions differ: cgspeed MotionBuilder legs stand 20° apart at rest);
* rigid parts (pelvis, each spine segment, neck, head with the face points, collar, hand with two fingertips,
  foot with the toes) take the world rotation of the mocap joint that carries them, applied to the model's
  rest offsets (both rest poses face +Z, Y up, arms out: the zero-rotation frame of each BVH is its rest).

The model's pelvis is placed at the mocap's hip midpoint (in metres). What the mocap does not hold stays at the
rest pose: the fingers (no CMU hand data), the collar shrug (constant in these releases), the toes of the
Daz-friendly skeleton (it has none).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smplcore.skeletons import read_bvh

# (model point, its parent point, how it moves: a role whose rotation carries it, or "dir:A:B" = the
# direction from role A's joint to role B's). L/R roles are expanded per side.
TREE: list[tuple[str, str, str]] = [
    ("left_hip", "pelvis", "ROOT"), ("right_hip", "pelvis", "ROOT"), ("spine1", "pelvis", "ROOT"),
    ("spine2", "spine1", "S1"), ("spine3", "spine2", "S2"),
    ("neck", "spine3", "S3"), ("left_collar", "spine3", "S3"), ("right_collar", "spine3", "S3"),
    ("head", "neck", "NECK"),
    ("nose", "head", "HEAD"), ("left_eye", "head", "HEAD"), ("right_eye", "head", "HEAD"),
    ("left_ear", "head", "HEAD"), ("right_ear", "head", "HEAD"),
] + [
    row
    for s, S in (("left", "L"), ("right", "R"))
    for row in (
        (f"{s}_shoulder", f"{s}_collar", f"{S}COLLAR"),
        (f"{s}_elbow", f"{s}_shoulder", f"dir:{S}SHOULDER:{S}ELBOW"),
        (f"{s}_wrist", f"{s}_elbow", f"dir:{S}ELBOW:{S}WRIST"),
        (f"{s}_hand", f"{s}_wrist", f"{S}WRIST"),
        (f"{s}_index", f"{s}_wrist", f"{S}WRIST"), (f"{s}_pinky", f"{s}_wrist", f"{S}WRIST"),
        (f"{s}_knee", f"{s}_hip", f"dir:{S}HIP:{S}KNEE"),
        (f"{s}_ankle", f"{s}_knee", f"dir:{S}KNEE:{S}ANKLE"),
        (f"{s}_foot", f"{s}_ankle", f"{S}ANKLE"),
        (f"{s}_big_toe", f"{s}_foot", f"{S}TOE"), (f"{s}_small_toe", f"{s}_foot", f"{S}TOE"),
    )
]  # fmt: skip


def _sided(left: dict[str, str], right: dict[str, str], **mid: str) -> dict[str, str]:
    return {**mid, **{"L" + k: v for k, v in left.items()}, **{"R" + k: v for k, v in right.items()}}


_LIMBS = ("COLLAR", "SHOULDER", "ELBOW", "WRIST", "HIP", "KNEE", "ANKLE", "TOE")

#: family → (Z up in the file?, role → BVH joint)
FAMILIES: dict[str, tuple[bool, dict[str, str]]] = {
    "daz": (False, _sided(
        dict(zip(_LIMBS, ("lCollar", "lShldr", "lForeArm", "lHand", "lThigh", "lShin", "lFoot", "lFoot"))),
        dict(zip(_LIMBS, ("rCollar", "rShldr", "rForeArm", "rHand", "rThigh", "rShin", "rFoot", "rFoot"))),
        ROOT="hip", S1="abdomen", S2="abdomen", S3="chest", NECK="neck", HEAD="head",
    )),
    "mb": (False, _sided(
        dict(zip(_LIMBS, ("LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftUpLeg", "LeftLeg", "LeftFoot",
                          "LeftToeBase"))),
        dict(zip(_LIMBS, ("RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightUpLeg", "RightLeg",
                          "RightFoot", "RightToeBase"))),
        ROOT="Hips", S1="LowerBack", S2="Spine", S3="Spine1", NECK="Neck1", HEAD="Head",
    )),
    "max": (False, _sided(
        dict(zip(_LIMBS, ("LeftCollar", "LeftShoulder", "LeftElbow", "LeftWrist", "LeftHip", "LeftKnee", "LeftAnkle",
                          "LeftToe"))),
        dict(zip(_LIMBS, ("RightCollar", "RightShoulder", "RightElbow", "RightWrist", "RightHip", "RightKnee",
                          "RightAnkle", "RightToe"))),
        ROOT="Hips", S1="lowerback", S2="Chest", S3="Chest2", NECK="Neck", HEAD="Head",
    )),
    "fair": (True, _sided(
        dict(zip(_LIMBS, ("LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftUpLeg", "LeftLeg", "LeftFoot",
                          "LeftToeBase"))),
        dict(zip(_LIMBS, ("RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightUpLeg", "RightLeg",
                          "RightFoot", "RightToeBase"))),
        ROOT="Hips", S1="Spine1", S2="Spine2", S3="Spine3", NECK="Neck", HEAD="Head",
    )),
}  # fmt: skip
Z_UP = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # (x, y, z) Z-up → (x, z, −y) Y-up


def family_of(names: list[str]) -> str:
    """The skeleton family of a BVH from its joint names."""
    for family, marker in (("daz", "abdomen"), ("mb", "LowerBack"), ("max", "lowerback"), ("fair", "Spine3")):
        if marker in names:
            return family
    raise ValueError(f"unknown skeleton (joints {names[:6]}...)")


def model_rest(model) -> dict[str, np.ndarray]:
    """The open model's rest output joints (mean shape), by name."""
    joints = np.asarray(model().joints, np.float64)[0]
    return dict(zip(model.joint_names, joints))


#: role → the role it is calibrated against (its parent); see :func:`calibration`.
CALIBRATED = {"NECK": "S3", "HEAD": "NECK", "LWRIST": "LELBOW", "RWRIST": "RELBOW", "LTOE": "LANKLE", "RTOE": "RANKLE"}


@dataclass
class Motion:
    """One clip at the kept frames: world rotations (T, 3, 3) and positions (T, 3) (Y up, file units) by role."""

    rot: dict[str, np.ndarray]
    pos: dict[str, np.ndarray]
    frames: np.ndarray
    family: str


def clip_motion(path: Path, fps: float, drop_first: bool) -> Motion:
    """Read one clip and keep its frames at about ``fps`` (frame 0 dropped when it is a reference pose)."""
    bvh = read_bvh(path)
    family = family_of(list(bvh.joint_names))
    z_up, roles = FAMILIES[family]
    index = {n: i for i, n in enumerate(bvh.joint_names)}
    missing = sorted({j for j in roles.values() if j not in index})
    if missing:
        raise ValueError(f"{path}: the {family} map names {missing}, absent from the file")
    step = max(1, int(round(1.0 / (bvh.frame_time * fps))))
    frames = np.arange(1 if drop_first else 0, bvh.num_frames, step)
    rot, pos = bvh.frames(frames).world_transforms()
    if z_up:
        rot = Z_UP @ rot @ Z_UP.T
        pos = pos @ Z_UP.T
    return Motion({r: rot[:, index[j]] for r, j in roles.items()}, {r: pos[:, index[j]] for r, j in roles.items()},
                  frames, family)  # fmt: skip


def _project_rotation(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def calibration(motions: list[Motion]) -> dict[str, np.ndarray]:
    """Per role of :data:`CALIBRATED`, the mean (chordal) local rotation relative to its parent role over the
    given clips (one performer's): the head, wrist and toe joints of the CMU skeletons have per-performer rest
    frames (uncalibrated, subject 05's walks come out looking at the floor, 43° down, and subject 02's head
    26° back), so a performer's average head/hand/toe posture is taken as the model's rest one."""
    out = {}
    for role, parent in CALIBRATED.items():
        local = np.concatenate([np.swapaxes(m.rot[parent], -1, -2) @ m.rot[role] for m in motions])
        out[role] = _project_rotation(local.mean(0))
    return out


def calibrated(motion: Motion, calib: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """World rotations by role with the calibrated roles' mean local rotation removed (parents first)."""
    rot = dict(motion.rot)
    for role, parent in CALIBRATED.items():  # parents precede children in CALIBRATED
        local = np.swapaxes(motion.rot[parent], -1, -2) @ motion.rot[role]
        rot[role] = rot[parent] @ local @ calib[role].T
    return rot


def targets(rest: dict[str, np.ndarray], motion: Motion, calib: dict[str, np.ndarray]):
    """(T, n, 3) model-skeleton targets re-posed by the mocap, and the n model point names."""
    rot, pos = calibrated(motion, calib), motion.pos
    out = {}
    hips_mid = 0.5 * (pos["LHIP"] + pos["RHIP"])
    scale = np.linalg.norm(rest["left_hip"] - rest["right_hip"]) / np.linalg.norm(pos["LHIP"][0] - pos["RHIP"][0])
    rest_mid = 0.5 * (rest["left_hip"] + rest["right_hip"])
    out["pelvis"] = hips_mid * scale - np.einsum("tij,j->ti", rot["ROOT"], rest_mid - rest["pelvis"])
    for child, parent, how in TREE:
        bone = rest[child] - rest[parent]
        if how.startswith("dir:"):
            _, a, b = how.split(":")
            d = pos[b] - pos[a]
            step = d / np.linalg.norm(d, axis=-1, keepdims=True) * np.linalg.norm(bone)
        else:
            step = np.einsum("tij,j->ti", rot[how], bone)
        out[child] = out[parent] + step
    names = list(out)
    return np.stack([out[n] for n in names], axis=1), names


@dataclass
class Retargeted:
    """One clip's fit: per kept frame the model's parameters and the fit's error."""

    body_pose: np.ndarray  # (T, 69)
    global_orient: np.ndarray  # (T, 3)
    transl: np.ndarray  # (T, 3)
    joint_error: np.ndarray  # (T,) mean over the targets (m)
    point_error: np.ndarray  # (T, n) per target (m)
    frames: np.ndarray  # (T,) frame indices in the file
    iterations: int
    seconds: float
    family: str


def retarget(model, rest, motion: Motion, calib, **fit_options) -> tuple[Retargeted, np.ndarray]:
    """Fit the open model (mean shape) to one clip's re-posed skeleton; also returns the (T, n, 3) targets."""
    from smplcore.fit import fit_joints

    pts, names = targets(rest, motion, calib)
    start = time.perf_counter()
    r = fit_joints(model, pts, names, fit_betas=False, betas=np.zeros((1, model.rig.num_betas)), **fit_options)
    seconds = time.perf_counter() - start
    out = model(**r.params)
    ids = [model.joint_names.index(n) for n in names]
    point_error = np.linalg.norm(np.asarray(out.joints, np.float64)[:, ids] - pts, axis=-1)
    return Retargeted(
        body_pose=np.asarray(r.params["body_pose"], np.float64),
        global_orient=np.asarray(r.params["global_orient"], np.float64),
        transl=np.asarray(r.params["transl"], np.float64),
        joint_error=np.asarray(r.joint_error, np.float64),
        point_error=point_error,
        frames=motion.frames,
        iterations=int(r.iterations),
        seconds=seconds,
        family=motion.family,
    ), pts
