"""fit_keypoints on what real detectors give: confidences, keypoints outside the image, people cut by the
image's edge, legs out of frame, the lean a 2D view cannot see; per-point errors, mask and plausibility."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import smplcore
from fakes_fit2d import CAMERA, natural_poses
from smplcore import fit
from smplcore import keypoints as kp
from smplcore.fit.plausibility import ImplausibleFitWarning


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def standing(model, batch: int, seed: int) -> dict[str, np.ndarray]:
    """People standing upright (the spine and hips near straight), turned ±45° about the vertical, facing
    the camera 2.5-4 m away."""
    rng = np.random.default_rng(seed)
    names = list(model.joint_names)
    params = natural_poses(model, batch, rng, spread=0.05)
    yaw = Rotation.from_rotvec(np.c_[np.zeros(batch), rng.uniform(-0.8, 0.8, batch), np.zeros(batch)])
    params["global_orient"] = (yaw * Rotation.from_rotvec([np.pi, 0.0, 0.0])).as_rotvec()
    pose = params["body_pose"]
    for joint in ("spine1", "spine2", "spine3", "left_hip", "right_hip"):
        j = names.index(joint) - 1
        pose[:, 3 * j : 3 * j + 3] *= 0.3
    for side in ("left", "right"):
        pose[:, 3 * (names.index(f"{side}_knee") - 1)] = rng.uniform(0.0, 0.2, batch)
    params["transl"][:, 2] = rng.uniform(2.5, 4.0, batch)
    return params


def torso_axis(joints: np.ndarray) -> np.ndarray:
    """(B, 3) unit vectors from the pelvis to the neck."""
    v = joints[:, 12] - joints[:, 0]
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def upper_body_photos(model, params, seed: int, guesses: bool):
    """Each body cut halfway between shoulders and hips by the image's bottom edge: (B, 17, 3) keypoints
    (2 px noise), the cameras (with the image size) and the true joints. Below the edge: OpenPose's zeros,
    or with ``guesses`` a detector's extrapolations (squeezed towards the edge, just outside it, with a
    confidence of 0.6, as MediaPipe's visibility often is)."""
    rng = np.random.default_rng(seed)
    joints = np.asarray(model(**params).joints, np.float64)
    uv = CAMERA.project(kp.convert(joints, model, "coco17")[0])
    edge = 0.5 * (uv[:, 5:7, 1].mean(1) + uv[:, 11:13, 1].mean(1))
    keypoints, cameras = [], []
    for b in range(len(uv)):
        pts = np.c_[uv[b] + rng.normal(0, 2.0, uv[b].shape), np.ones(17)]
        below = uv[b, :, 1] > edge[b]
        if guesses:
            pts[below, 1] = edge[b] + 3.0 + 0.3 * (uv[b, below, 1] - edge[b])
            pts[below, 2] = 0.6
        else:
            pts[below] = 0.0
        keypoints.append(pts)
        cameras.append(fit.Camera(focal=1000.0, center=(500.0, 500.0), image_size=(1000.0, edge[b])))
    return np.array(keypoints), cameras, joints


def test_a_standing_body_does_not_lean_towards_the_camera(open_model):
    # 3 px of noise on 17 keypoints hardly tells a lean along the line of sight: the upright prior decides
    params = standing(open_model, 8, 2)
    joints = np.asarray(open_model(**params).joints, np.float64)
    rng = np.random.default_rng(2)
    uv = CAMERA.project(kp.convert(joints, open_model, "coco17")[0]) + rng.normal(0, 3.0, (8, 17, 2))
    r = fit.fit_keypoints(open_model, np.concatenate([uv, np.ones((8, 17, 1))], -1), camera=CAMERA)
    got = np.asarray(open_model(**r.params).joints, np.float64)
    lean = np.degrees(np.arccos(np.clip(np.sum(torso_axis(got) * torso_axis(joints), 1), -1, 1)))
    assert lean.mean() < 6.0 and lean.max() < 10.0, lean  # before the prior: 12° mean, up to 21°


def test_an_upper_body_photo_gives_an_upright_standing_body_and_a_warning(open_model):
    params = standing(open_model, 4, 1)
    keypoints, cameras, joints = upper_body_photos(open_model, params, 1, guesses=False)
    names = list(open_model.joint_names)
    for b in range(4):
        with pytest.warns(fit.PartialViewWarning, match="legs not visible"):
            r = fit.fit_keypoints(open_model, keypoints[b : b + 1], camera=cameras[b])
        got = np.asarray(open_model(**r.params).joints, np.float64)
        angle = np.degrees(np.arccos(torso_axis(got)[0] @ np.array([0.0, -1.0, 0.0])))  # the camera's up: -y
        assert angle < 8.0, (b, angle)  # before: up to 18° off the vertical
        knees = r.params["body_pose"][0, [3 * (names.index(f"{s}_knee") - 1) for s in ("left", "right")]]
        assert np.all(np.abs(knees) < 0.4)  # standing legs: the prior's
        assert abs(got[0, 0, 2] - joints[b, 0, 2]) < 0.1 * joints[b, 0, 2]  # at the right distance (body size: ±)


def test_keypoints_outside_the_image_do_not_pull(open_model):
    # a detector's guesses for the legs beyond the bottom edge would shrink the body and push it away
    params = standing(open_model, 4, 1)
    keypoints, cameras, joints = upper_body_photos(open_model, params, 1, guesses=True)
    for b in range(4):
        with pytest.warns(fit.PartialViewWarning, match="legs not visible"):
            r = fit.fit_keypoints(open_model, keypoints[b : b + 1], camera=cameras[b])
        got = np.asarray(open_model(**r.params).joints, np.float64)
        assert abs(got[0, 0, 2] - joints[b, 0, 2]) < 0.1 * joints[b, 0, 2], b  # before: up to 0.76 m (25 %) too far
        outside = keypoints[b, :, 1] > cameras[b].image_size[1]
        assert not r.mask[0, outside].any() and r.mask[0, ~outside].all()
        assert np.isnan(r.point_error[0, outside]).all()


def test_reprojection_error_is_over_the_keypoints_used_weighted_by_confidence(open_model):
    params = standing(open_model, 1, 3)
    joints = np.asarray(open_model(**params).joints, np.float64)
    uv = CAMERA.project(kp.convert(joints, open_model, "coco17")[0])[0]
    keypoints = np.c_[uv, np.ones(17)]
    keypoints[9] = [uv[9, 0] + 60.0, uv[9, 1], 0.15]  # a wrist guessed 60 px off, with low confidence
    keypoints[10] = [0.0, 0.0, 0.05]  # below min_confidence: not used
    r = fit.fit_keypoints(open_model, keypoints[None], camera=CAMERA)
    assert r.point_error.shape == (1, 17) and r.mask.shape == (1, 17)
    assert r.mask[0, 9] and not r.mask[0, 10] and np.isnan(r.point_error[0, 10])
    used = r.mask[0]
    plain = np.nanmean(r.point_error[0, used])
    weighted = np.sum(r.point_error[0, used] * keypoints[used, 2]) / keypoints[used, 2].sum()
    assert r.reprojection_error[0] == pytest.approx(weighted)
    assert r.point_error[0, 9] > 20.0 and r.reprojection_error[0] < plain  # the wild guess counts 0.15


def test_plausibility_of_2d_fits(open_model):
    params = standing(open_model, 2, 4)
    joints = np.asarray(open_model(**params).joints, np.float64)
    uv = CAMERA.project(kp.convert(joints, open_model, "coco17")[0])
    keypoints = np.concatenate([uv, np.ones((2, 17, 1))], -1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ImplausibleFitWarning)
        r = fit.fit_keypoints(open_model, keypoints, camera=CAMERA)
    assert r.plausibility is not None and r.plausible.all()
    # the limits switched off and a start bent backwards: the result says so, with a warning
    names = list(open_model.joint_names)
    init = {k: v.copy() for k, v in params.items()}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        init["body_pose"][:, 3 * (names.index(f"{side}_elbow") - 1) + 1] = sign * 1.5
    with pytest.warns(ImplausibleFitWarning, match="elbow"):
        bad = fit.fit_keypoints(open_model, keypoints, camera=CAMERA, init=init, joint_limits=0.0, bending=0.0,
                                max_iter=0)  # fmt: skip
    assert not bad.plausible.any()


def test_camera_image_size():
    cam = fit.Camera.from_image_size(640, 480)
    assert cam.image_size == (640.0, 480.0) and "image_size=(640, 480)" in repr(cam)
    inside = cam.inside(np.array([[10.0, 10.0], [-1.0, 5.0], [639.0, 479.0], [700.0, 10.0]]))
    assert inside.tolist() == [True, False, True, False]
    assert fit.Camera(focal=500.0, center=(320.0, 240.0)).inside(np.array([[-5.0, 1e6]])).all()  # size unknown
    moved = cam.replace(focal=900.0)
    assert moved.image_size == cam.image_size and moved.focal.tolist() == [900.0, 900.0]
    with pytest.raises(ValueError, match="image_size"):
        fit.Camera(focal=500.0, center=(320.0, 240.0), image_size=(0, 480))
    with pytest.raises(TypeError, match="replace"):
        cam.replace(fov=30)


def test_up_is_checked(open_model):
    keypoints = np.c_[np.full((17, 2), 500.0) + np.arange(17)[:, None] * 10, np.ones(17)][None]
    with pytest.raises(ValueError, match="up"):
        fit.fit_keypoints(open_model, keypoints, camera=CAMERA, up=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="upright"):
        fit.fit_keypoints(open_model, keypoints, camera=CAMERA, upright=-1.0)
