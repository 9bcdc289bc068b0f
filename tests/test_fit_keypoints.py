"""fit_keypoints and fit.Camera: 2D keypoints to parameters (SMPLify-style), priors, the GMM file, errors."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import smplcore
from fakes_fit2d import CAMERA, natural_poses, pa_mpjpe, scene, write_fake_gmm
from smplcore import fit
from smplcore import keypoints as kp
from smplcore.errors import ModelFileError, ShapeError
from smplcore.fit.body import FitBody
from smplcore.fit.priors import BENDING, GMMPrior, bending_residuals, joint_limits, limit_residuals


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


@pytest.fixture(scope="module")
def synthetic(open_model):
    rng = np.random.default_rng(0)
    params = natural_poses(open_model, 6, rng)
    keypoints, exact, j3 = scene(open_model, params, rng, noise=1.0)
    return params, keypoints, exact, j3


@pytest.fixture(scope="module")
def fitted(open_model, synthetic):
    return fit.fit_keypoints(open_model, synthetic[1], camera=CAMERA)


# -- the camera ----------------------------------------------------------------------------------


def test_camera_projects_in_the_opencv_convention():
    cam = fit.Camera(focal=(800.0, 900.0), center=(320.0, 240.0))
    uv = cam.project(np.array([[0.0, 0.0, 2.0], [0.5, 0.25, 2.0]]))
    np.testing.assert_allclose(uv, [[320.0, 240.0], [520.0, 352.5]])  # x right, y down, z forward


def test_camera_extrinsics_map_world_to_camera():
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_rotvec([0.1, -0.4, 0.2]).as_matrix()
    cam = fit.Camera(focal=1000.0, center=(0.0, 0.0), rotation=rot, translation=(0.1, 0.2, 3.0))
    x = np.array([[0.3, -0.2, 0.5]])
    xc = x @ rot.T + [0.1, 0.2, 3.0]
    np.testing.assert_allclose(cam.project(x), 1000.0 * xc[:, :2] / xc[:, 2:])
    np.testing.assert_allclose(fit.Camera(1000.0, (0, 0), rotation=[0.1, -0.4, 0.2]).rotation, rot, atol=1e-12)


def test_camera_jacobian_matches_finite_differences():
    cam = fit.Camera(focal=(900.0, 950.0), center=(10.0, 20.0), rotation=[0.2, 0.1, -0.3], translation=(0, 0, 2))
    x = np.array([0.2, -0.3, 1.0])
    _, jac = cam.project_jacobian(x)
    eps = 1e-6
    num = np.stack([(cam.project(x + eps * e) - cam.project(x - eps * e)) / (2 * eps) for e in np.eye(3)], -1)
    np.testing.assert_allclose(jac, num, rtol=1e-6, atol=1e-6)


def test_camera_from_image_size_centres_the_principal_point():
    cam = fit.Camera.from_image_size(640, 480)
    np.testing.assert_allclose(cam.center, [320.0, 240.0])
    np.testing.assert_allclose(cam.focal, [800.0, 800.0])  # the diagonal


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"focal": -1.0, "center": (0, 0)}, "focal"),
        ({"focal": 1.0, "center": None}, "center"),
        ({"focal": 1.0, "center": (0, 0, 0)}, "center"),
        ({"focal": 1.0, "center": (0, 0), "rotation": np.ones((3, 3))}, "rotation"),
        ({"focal": 1.0, "center": (0, np.nan)}, "center"),
    ],
)
def test_camera_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        fit.Camera(**kwargs)


# -- fitting synthetic scenes ------------------------------------------------------------------------


def test_fit_reduces_reprojection_error_below_the_noise(open_model, synthetic, fitted):
    params, keypoints, exact, _ = synthetic
    noise = np.linalg.norm(keypoints[..., :2] - exact, axis=-1).mean(1)  # about 1.25 px for 1 px noise
    assert np.all(fitted.reprojection_error < noise), (fitted.reprojection_error, noise)
    again = np.asarray(open_model(**fitted.params).joints)
    uv = CAMERA.project(kp.convert(again, open_model, "coco17")[0])
    np.testing.assert_allclose(
        np.linalg.norm(uv - keypoints[..., :2], axis=-1).mean(1), fitted.reprojection_error, rtol=1e-6
    )


def test_fit_recovers_the_3d_pose_up_to_similarity(open_model, synthetic, fitted):
    params, _, _, j3 = synthetic
    got = kp.convert(np.asarray(open_model(**fitted.params).joints), open_model, "coco17")[0]
    error = pa_mpjpe(j3, got)
    rest = kp.convert(np.asarray(open_model(betas=params["betas"]).joints), open_model, "coco17")[0]
    assert error.mean() < 0.05 and error.max() < 0.08, error  # depth is ambiguous in 2D (about 35 mm here)
    assert np.all(error < 0.6 * pa_mpjpe(j3, rest))  # far better than the rest pose


def test_the_body_is_placed_in_camera_space(open_model, synthetic, fitted):
    transl = np.asarray(fitted.params["transl"])
    truth = synthetic[0]["transl"]
    assert np.all(np.abs(transl[:, 2] - truth[:, 2]) < 0.25 * truth[:, 2])  # depth from the torso's size
    assert np.all(np.abs(transl[:, :2] - truth[:, :2]) < 0.1)


def test_priors_keep_elbows_and_knees_bending_the_right_way(open_model, fitted):
    names = list(open_model.joint_names)
    pose = np.asarray(fitted.params["body_pose"])
    for joint, axis, sign in BENDING:
        value = sign * pose[:, (names.index(joint) - 1) * 3 + axis]
        assert np.all(value < 0.05), (joint, value)  # sign · θ > 0 is the wrong way


def test_bending_prior_flips_a_backward_elbow(open_model):
    names = list(open_model.joint_names)
    rng = np.random.default_rng(3)
    params = natural_poses(open_model, 1, rng)
    keypoints, _, _ = scene(open_model, params, rng, noise=0.5)
    col = (names.index("left_elbow") - 1) * 3 + 1
    init = {k: v.copy() for k, v in params.items()}
    init["body_pose"][:, col] *= -1.0  # start bent backwards
    free = fit.fit_keypoints(open_model, keypoints, camera=CAMERA, init=init, bending=0.0, joint_limits=0.0)
    kept = fit.fit_keypoints(open_model, keypoints, camera=CAMERA, init=init)
    # the hinge is zero from 0 on: the prior brings the elbow out of the backward bend (within 0.6°)
    assert kept.params["body_pose"][0, col] < 0.01
    assert free.reprojection_error[0] < 3.0 and kept.reprojection_error[0] < 3.0


def test_people_in_one_image_are_independent(open_model, synthetic):
    keypoints = synthetic[1]
    both = fit.fit_keypoints(open_model, keypoints[:2], camera=CAMERA)
    one = fit.fit_keypoints(open_model, keypoints[1:2], camera=CAMERA)
    np.testing.assert_allclose(both.params["body_pose"][1], one.params["body_pose"][0], atol=1e-6)


def test_sequences_share_betas_and_smooth(open_model):
    rng = np.random.default_rng(5)
    params = natural_poses(open_model, 1, rng)
    frames = 6
    seq = {k: np.repeat(v, frames, 0) for k, v in params.items()}
    seq["body_pose"] = seq["body_pose"] + np.linspace(0, 0.2, frames)[:, None]
    keypoints, _, _ = scene(open_model, seq, rng, noise=2.0)
    plain = fit.fit_keypoints(open_model, keypoints, camera=CAMERA)
    smooth = fit.fit_keypoints(open_model, keypoints, camera=CAMERA, share_betas=True, smoothness=1e-2)
    betas = np.asarray(smooth.params["betas"])
    np.testing.assert_allclose(betas, np.broadcast_to(betas[:1], betas.shape), atol=1e-9)

    def jitter(r):
        return np.abs(np.diff(np.diff(np.asarray(r.params["body_pose"]), axis=0), axis=0)).mean()

    assert jitter(smooth) < 0.5 * jitter(plain)
    assert smooth.reprojection_error.mean() < 4.0


def test_torch_and_numpy_models_give_the_same_fit(synthetic):
    torch = pytest.importorskip("torch")
    keypoints = synthetic[1][:1]
    tmodel = smplcore.create(model_type="open", dtype=torch.float64)
    nmodel = smplcore.BodyModel(model_type="open", dtype=np.float64)
    rt = fit.fit_keypoints(tmodel, torch.as_tensor(keypoints), camera=CAMERA)
    rn = fit.fit_keypoints(nmodel, keypoints, camera=CAMERA)
    assert isinstance(rt.params["body_pose"], torch.Tensor)
    np.testing.assert_allclose(rt.params["body_pose"].numpy(), rn.params["body_pose"], atol=1e-6)
    np.testing.assert_allclose(rt.reprojection_error, rn.reprojection_error, atol=1e-6)


def test_openpose_convention_and_a_regressor(open_model, synthetic):
    params = {k: v[:1] for k, v in synthetic[0].items()}
    rng = np.random.default_rng(1)
    keypoints, _, _ = scene(open_model, params, rng, convention="openpose25")
    r = fit.fit_keypoints(open_model, keypoints, convention="openpose25", camera=CAMERA)
    assert r.reprojection_error[0] < 1.5
    reg = kp.open_model_regressor("coco17")
    verts = np.asarray(open_model(**params).vertices, np.float64)
    uv = CAMERA.project(reg.apply(verts))
    points = np.concatenate([uv + rng.normal(0, 1, uv.shape), np.ones((1, 17, 1))], -1)
    r = fit.fit_keypoints(open_model, points, camera=CAMERA, regressor=reg)
    assert r.reprojection_error[0] < 1.5


def test_objective_gradient_matches_finite_differences(open_model, synthetic):
    from smplcore.fit import keypoints2d, reprojection

    body = FitBody.from_model(open_model)
    kmap = keypoints2d.keypoint_map(body, open_model, "coco17")
    width = body.num_pose + body.num_coeffs + 3
    free = np.ones(width, bool)
    keypoints = synthetic[1][:2]
    terms = keypoints2d._terms(
        body, kmap, CAMERA, keypoints[..., :2], keypoints[..., 2], np.full(2, 0.004), 50.0, free,
        np.zeros(width, bool), shape_prior=1e-3, pose_prior=1e-4, limit_prior=1.0, bend_prior=1.0,
    )  # fmt: skip
    p = synthetic[0]
    rng = np.random.default_rng(2)
    x = np.concatenate([p["global_orient"][:2], p["body_pose"][:2], p["betas"][:2], p["transl"][:2]], 1)
    x = x + rng.normal(0, 0.05, x.shape)
    _, _, grad = reprojection.evaluate(body, terms, x)
    eps = 1e-6
    num = np.empty_like(grad)
    for i in range(width):
        step = np.zeros(width)
        step[i] = eps
        up = reprojection.evaluate(body, terms, x + step, system=False)[0]
        down = reprojection.evaluate(body, terms, x - step, system=False)[0]
        num[:, i] = (up - down) / (4 * eps)  # cost = Σ r², grad = Jᵀ r = ½ ∇cost
    np.testing.assert_allclose(grad, num, rtol=1e-4, atol=1e-7)


# -- priors --------------------------------------------------------------------------------------


def test_joint_limits_mirror_left_to_right():
    lo, hi = joint_limits(["left_elbow", "right_elbow", "pelvis"])
    np.testing.assert_allclose(lo[1], [lo[0][0], -hi[0][1], -hi[0][2]])
    np.testing.assert_allclose(hi[1], [hi[0][0], -lo[0][1], -lo[0][2]])
    assert np.degrees(lo[0][1]) == pytest.approx(-150.0)  # left elbow flexion: −y, AAOS 150°
    np.testing.assert_allclose(lo[2], -np.pi)  # no limit on the pelvis
    res, diag = limit_residuals(np.array([[-3.0, 0.0, 0.5]]), lo[0], hi[0])
    np.testing.assert_allclose(res, [[-3.0 - lo[0][0], 0.0, 0.5 - hi[0][2]]])
    np.testing.assert_allclose(diag, [[1.0, 0.0, 1.0]])


def test_bending_residuals_are_hinges():
    res, jac = bending_residuals(np.array([[0.3, -0.2]]), np.array([0, 1]), np.array([1.0, 1.0]))
    np.testing.assert_allclose(res, [[0.3, 0.0]])
    np.testing.assert_allclose(jac, [[1.0, 0.0]])


def test_gmm_prior_loads_a_fake_file_through_the_safe_loader(tmp_path, open_model, synthetic):
    path = write_fake_gmm(tmp_path / "gmm_08.pkl")
    gmm = GMMPrior.load(path)
    assert gmm.means.shape == (8, 69) and gmm.chol.shape == (8, 69, 69)
    with open(path, "rb") as fh:
        raw = pickle.load(fh)
    theta = np.random.default_rng(0).normal(0, 0.1, (3, 69))
    best, res, jac = gmm.residuals(theta)
    # the chosen component has the largest weighted density
    from scipy.stats import multivariate_normal

    dens = np.stack([w * multivariate_normal(m, c).pdf(theta) for m, c, w in zip(raw["means"], raw["covars"],
                     raw["weights"], strict=True)], 1)  # fmt: skip
    np.testing.assert_array_equal(best, dens.argmax(1))
    nll = 0.5 * np.sum(res * res, 1) + gmm.penalty[best]
    const = 0.5 * 69 * np.log(2 * np.pi)
    np.testing.assert_allclose(nll + const, -np.log(dens.max(1)), rtol=1e-8)
    np.testing.assert_allclose(jac @ (theta - gmm.means[best])[..., None], res[..., None], atol=1e-12)
    marginal = gmm.marginal(63)
    np.testing.assert_allclose(np.linalg.inv(marginal.chol[0] @ marginal.chol[0].T), raw["covars"][0][:63, :63])
    r = fit.fit_keypoints(open_model, synthetic[1][:1], camera=CAMERA, gmm=path)
    assert np.isfinite(r.reprojection_error).all() and r.reprojection_error[0] < 3.0


def test_gmm_file_with_code_is_refused(tmp_path):
    import os

    class Evil:
        def __reduce__(self):
            return (os.getcwd, ())

    path = tmp_path / "gmm_08.pkl"
    path.write_bytes(pickle.dumps({"means": Evil()}))
    with pytest.raises(ModelFileError, match="refused to load.*nothing in the file was run"):
        GMMPrior.load(path)
    path.write_bytes(pickle.dumps({"means": np.zeros((8, 69))}))
    with pytest.raises(ModelFileError, match="covars"):
        GMMPrior.load(path)


# -- errors --------------------------------------------------------------------------------------


def test_errors_name_the_argument(open_model, synthetic):
    keypoints = synthetic[1][:1]
    with pytest.raises(ValueError, match="camera"):
        fit.fit_keypoints(open_model, keypoints)
    with pytest.raises(ShapeError, match="keypoints"):
        fit.fit_keypoints(open_model, keypoints[:, :10], camera=CAMERA)
    with pytest.raises(ShapeError, match="keypoints"):
        fit.fit_keypoints(open_model, keypoints[..., :2], camera=CAMERA)
    with pytest.raises(ValueError, match="convention"):
        fit.fit_keypoints(open_model, keypoints, convention="not-a-convention", camera=CAMERA)
    bad = keypoints.copy()
    bad[0, 3, 0] = np.nan
    with pytest.raises(ValueError, match="keypoints.*non-finite"):
        fit.fit_keypoints(open_model, bad, camera=CAMERA)
    few = keypoints.copy()
    few[0, 4:, 2] = 0.0
    with pytest.raises(ValueError, match="keypoints.*min_points"):
        fit.fit_keypoints(open_model, few, camera=CAMERA)
    with pytest.raises(TypeError, match="camera"):
        fit.fit_keypoints(open_model, keypoints, camera=(1000.0, 500.0))


def test_low_confidence_points_are_ignored(open_model, synthetic):
    keypoints = synthetic[1][:1].copy()
    keypoints[0, 9] = [0.0, 0.0, 0.05]  # a wild left wrist, below min_confidence
    r = fit.fit_keypoints(open_model, keypoints, camera=CAMERA)
    assert r.reprojection_error[0] < 1.5


@pytest.mark.parametrize("model_type", ["smpl", "smplx"])
def test_fake_official_models_fit_too(fake_models, model_type):
    model = smplcore.BodyModel(fake_models[f"{model_type}_neutral_npz"], model_type=model_type, dtype=np.float64)
    width = 69 if model_type == "smpl" else 63
    rng = np.random.default_rng(4)
    params = {
        "global_orient": np.array([[np.pi, 0.1, 0.0]]),
        "body_pose": rng.normal(0, 0.05, (1, width)),
        "transl": np.array([[0.0, 0.1, 4.0]]),
    }
    keypoints, exact, _ = scene(model, params, rng, noise=0.5)
    r = fit.fit_keypoints(model, keypoints, camera=CAMERA, min_points=5)
    start = np.linalg.norm(CAMERA.project(kp.convert(np.asarray(model(transl=params["transl"]).joints, np.float64),
                                                     model, "coco17")[0]) - keypoints[..., :2], axis=-1)  # fmt: skip
    assert set(r.params) >= {"global_orient", "body_pose", "betas", "transl"}
    assert r.reprojection_error[0] < 0.05 * start.mean()


def test_a_moved_camera_sees_the_body_in_its_world_frame(open_model):
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_rotvec([0.0, 0.4, 0.0]).as_matrix()  # the camera turned 23° about the vertical
    cam = fit.Camera(focal=1000.0, center=(500.0, 500.0), rotation=rot, translation=(0.2, -0.1, 1.0))
    rng = np.random.default_rng(8)
    params = natural_poses(open_model, 2, rng)
    # the bodies in front of the moved camera: world = Rᵀ (camera − t)
    params["transl"] = (params["transl"] - cam.translation) @ rot
    go = Rotation.from_matrix(rot.T @ Rotation.from_rotvec(params["global_orient"]).as_matrix()).as_rotvec()
    params["global_orient"] = go
    keypoints, exact, _ = scene(open_model, params, rng, camera=cam)
    r = fit.fit_keypoints(open_model, keypoints, camera=cam)
    noise = np.linalg.norm(keypoints[..., :2] - exact, axis=-1).mean(1)
    assert np.all(r.reprojection_error < noise)
    assert np.all(np.linalg.norm(np.asarray(r.params["transl"]) - params["transl"], axis=1) < 0.5)
