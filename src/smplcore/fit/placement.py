"""Stage 1 of :func:`smplcore.fit.fit_keypoints`: the body in its rest pose placed in front of the camera.

The depth comes from the size of the body's rigid part in the image: the torso's keypoints (shoulders,
hips, neck) when three or more of them are used, else the torso's and the head's together (a person cut
at the hips shows shoulders and head), against the same points of the rest body (metres), at the
keypoints' centre. The arms and legs are left out: in the rest pose they are stretched (a T), in the image
they are not, and a body sized by them would be placed too far away. Then the translation and the global
orientation are fitted to the torso and head keypoints (the head tells facing the camera from facing
away), from two starts (facing the camera and facing away; the better is kept), with the upright prior
of the later stages.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.fit.body import FitBody
from smplcore.fit.camera import Camera
from smplcore.fit.reprojection import KeypointMap, keypoints_3d, levenberg_marquardt
from smplcore.fit.solver import State

TORSO = ("left_shoulder", "right_shoulder", "left_hip", "right_hip", "neck", "mid_hip", "pelvis")
HEAD = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "head", "head_top")


def rotation_of(camera: Camera, facing: np.ndarray) -> np.ndarray:
    """Axis-angle in the world of a body orientation given in camera coordinates."""
    from scipy.spatial.transform import Rotation

    cam = Rotation.from_rotvec(facing).as_matrix()
    return Rotation.from_matrix(camera.rotation.T @ cam).as_rotvec()


def rigid_points(names: tuple[str, ...], available: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(B, K) the keypoints each body is sized and oriented by in stage 1: its torso's when three or more
    are used, else its torso's and head's, else every used keypoint."""
    torso = np.array([n in TORSO for n in names]) & available
    upper = torso | (np.array([n in HEAD for n in names]) & available)
    used = weights > 0
    out = used & torso
    few = out.sum(1) < 3
    out[few] = used[few] & upper
    few = out.sum(1) < 3
    out[few] = used[few]
    return out


def initial_translation(body, kmap, camera, state, targets, weights) -> tuple[np.ndarray, np.ndarray]:
    """Translations (B, 3) putting the rest body at the depth where its rigid part (:func:`rigid_points`)
    has the keypoints' size in the image, centred on them; and (B,) metres per pixel there."""
    pts, _ = keypoints_3d(body, kmap, state)
    rigid = rigid_points(kmap.names, kmap.available, weights)
    transl = np.empty((len(targets), 3))
    for b in range(len(targets)):
        use = rigid[b]
        cam = camera.to_camera(pts[b, use])
        size3 = np.sqrt(np.mean(np.sum((cam[:, :2] - cam[:, :2].mean(0)) ** 2, axis=1)))
        uv = targets[b, use] / camera.focal
        size2 = np.sqrt(np.mean(np.sum((uv - uv.mean(0)) ** 2, axis=1)))
        depth = size3 / max(size2, 1e-9)
        centre = (targets[b, use].mean(0) - camera.center) / camera.focal
        want = np.array([centre[0] * depth, centre[1] * depth, depth])  # camera coords of the centroid
        have = cam.mean(0)
        transl[b] = state.transl[b] + camera.rotation.T @ (want - have)
    depth = (transl @ camera.rotation.T + camera.translation)[:, 2]
    return transl, np.maximum(depth, 0.1) / camera.focal.mean()


def place(setup: Any, camera: Camera, terms_of, go_cols, transl_cols, scale=None):
    """Stage 1 (see the module docstring) for the bodies of ``setup``; ``terms_of(camera, targets,
    weights, scale, free)`` builds the stage's terms. Returns the state, (B,) metres per pixel at the
    bodies (``scale`` when given) and the iterations run."""
    body: FitBody = setup.body
    kmap: KeypointMap = setup.kmap
    targets, weights = setup.targets, setup.weights
    batch = len(targets)
    q, k = body.num_pose, body.num_coeffs
    facings = ((np.pi, 0.0, 0.0), (0.0, 0.0, np.pi)) if "global_orient" not in setup.given else (None,)
    candidates = []
    for facing in facings:
        state = setup.start.copy()
        if facing is not None:
            state.pose[:, go_cols] = rotation_of(camera, np.array(facing))
        transl, placed = initial_translation(body, kmap, camera, state, targets, weights)
        if "transl" not in setup.given:
            state.transl = transl
        candidates.append((state, placed if scale is None else scale))
    rigid = np.array([n in TORSO + HEAD for n in kmap.names])  # the head tells facing from facing away
    w1 = np.where(((weights > 0) & rigid).sum(1, keepdims=True) >= 3, weights * rigid, weights)
    free = np.zeros(q + k + 3, bool)
    free[go_cols] = free[transl_cols] = True
    both = State(*(np.concatenate([getattr(c[0], f) for c in candidates]) for f in ("pose", "coeffs", "transl")))
    scale2 = np.concatenate([c[1] for c in candidates])
    reps = len(candidates)
    upright = np.tile(np.broadcast_to(np.asarray(setup.upright, np.float64), (batch,)), reps)
    terms = terms_of(camera, np.tile(targets, (reps, 1, 1)), np.tile(w1, (reps, 1)), scale2, free, upright)
    both, cost, _, iterations = levenberg_marquardt(body, terms, both, max_iter=setup.max_iter, tol=setup.tol)
    pick = np.argmin(cost.reshape(reps, batch), axis=0) * batch + np.arange(batch)
    state = State(both.pose[pick], both.coeffs[pick], both.transl[pick])
    return state, scale2[pick], iterations
