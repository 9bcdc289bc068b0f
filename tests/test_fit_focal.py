"""fit_keypoints(estimate_focal=True): the focal column of the objective, the depth that moves with it,
recovery on an informative scene, the prior, and the CLI's camera choices (--focal, the image diagonal by
default, --estimate-focal) and priors (--vposer, --gmm)."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from fakes_fit2d import CAMERA, natural_poses, pa_mpjpe, scene, write_fake_gmm, write_openpose
from smplcore import fit
from smplcore import keypoints as kp
from smplcore.cli import main
from smplcore.fit import keypoints2d, reprojection
from smplcore.fit.body import FitBody

GUESS = fit.Camera.from_image_size(1000, 1000)  # focal = the diagonal, 1414 px


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def _people(model, count, near, far, focal, seed, noise=1.0):
    """``count`` people ``near``..``far`` metres in front of a camera of focal length ``focal``."""
    rng = np.random.default_rng(seed)
    camera = fit.Camera(focal=focal, center=(500.0, 500.0))
    params = natural_poses(model, count, rng)
    params["transl"][:, 2] = rng.uniform(near, far, count)
    params["transl"][:, 0] = rng.uniform(-0.25, 0.25, count) * params["transl"][:, 2]
    keypoints, exact, j3 = scene(model, params, rng, noise=noise, camera=camera)
    return params, keypoints, exact, j3


def _focal_terms(model, camera, keypoints, batch):
    body = FitBody.from_model(model)
    kmap = keypoints2d.keypoint_map(body, model, "coco17")
    width = body.num_pose + body.num_coeffs + 3
    terms = keypoints2d._terms(
        body,
        kmap,
        camera,
        keypoints[..., :2],
        keypoints[..., 2],
        np.full(batch, 0.004),
        50.0,
        np.ones(width + 1, bool),
        np.zeros(width + 1, bool),
        shape_prior=1e-3,
        pose_prior=1e-4,
        limit_prior=1.0,
        bend_prior=1.0,
    )
    terms.estimate_focal, terms.focal_prior, terms.focal_centre = True, 1e-3, 0.2
    return body, terms, width


def test_focal_column_gradient_matches_finite_differences(open_model):
    camera = fit.Camera(
        focal=(900.0, 950.0), center=(500.0, 480.0), rotation=[0.1, 0.2, 0.0], translation=(0.1, 0, 0.5)
    )
    params, keypoints, _, _ = _people(open_model, 2, 3.0, 5.0, 1000.0, seed=0)
    body, terms, width = _focal_terms(open_model, camera, keypoints, 2)
    rng = np.random.default_rng(1)
    x = np.concatenate(
        [params["global_orient"], params["body_pose"], params["betas"], params["transl"], np.full((2, 1), 0.1)], 1
    ) + rng.normal(0, 0.03, (2, width + 1))
    _, _, grad = reprojection.evaluate(body, terms, x)
    eps = 1e-6
    num = np.empty_like(grad)
    for i in range(width + 1):
        step = np.zeros(width + 1)
        step[i] = eps
        up = reprojection.evaluate(body, terms, x + step, system=False)[0]
        down = reprojection.evaluate(body, terms, x - step, system=False)[0]
        num[:, i] = (up - down) / (4 * eps)
    np.testing.assert_allclose(grad, num, rtol=1e-4, atol=1e-9)
    assert np.abs(grad[:, -1]).max() > 1e-6  # the focal column is not idle


def test_the_depth_moves_with_the_focal_length(open_model):
    camera = fit.Camera(focal=1000.0, center=(500.0, 500.0), rotation=[0.0, 0.3, 0.0], translation=(0.2, 0.0, 1.0))
    params, keypoints, _, _ = _people(open_model, 2, 3.0, 5.0, 1000.0, seed=2)
    body, terms, width = _focal_terms(open_model, camera, keypoints, 2)
    x = np.concatenate(
        [params["global_orient"], params["body_pose"], params["betas"], params["transl"], np.full((2, 1), np.log(1.5))],
        1,
    )
    transl = reprojection.focal_translation(body, camera, x)
    # R T + t = 1.5 (R T̃ + t): the root's camera coordinates scale with the focal length
    np.testing.assert_allclose(camera.to_camera(transl), 1.5 * camera.to_camera(params["transl"]), atol=1e-12)
    x0 = x.copy()
    x0[:, -1] = 0.0
    np.testing.assert_allclose(reprojection.focal_translation(body, camera, x0), params["transl"], atol=1e-12)
    # the pixels are those of the moved bodies seen with 1.5 f
    longer = fit.Camera(focal=1500.0, center=camera.center, rotation=camera.rotation, translation=camera.translation)
    moved = {**params, "transl": transl}
    pts = kp.convert(np.asarray(open_model(**moved).joints), open_model, "coco17")[0]
    e = reprojection.evaluate(body, terms, x, system=False)[0]
    terms_fixed = keypoints2d._terms(
        body,
        terms.kmap,
        longer,
        terms.targets,
        terms.weights,
        terms.scale,
        50.0,
        np.ones(width, bool),
        np.zeros(width, bool),
        shape_prior=1e-3,
        pose_prior=1e-4,
        limit_prior=1.0,
        bend_prior=1.0,
    )
    state = reprojection.unflat(body, x)
    state.transl = transl
    expected = reprojection.evaluate(body, terms_fixed, reprojection.flat(state), system=False)[0]
    expected += 1e-3 / 2 * (np.log(1.5) - 0.2) ** 2  # the focal prior, half per body
    np.testing.assert_allclose(e, expected, rtol=1e-12)
    np.testing.assert_allclose(
        reprojection.reprojection(body, terms_fixed, state),
        np.linalg.norm(longer.project(pts) - keypoints[..., :2], axis=-1),
        atol=1e-9,
    )


def test_a_wide_angle_camera_is_recovered_from_people_near_it(open_model):
    # six people 1.5-3 m from a 71° camera (f = 707 px); the guess is the diagonal, twice that
    params, keypoints, exact, j3 = _people(open_model, 6, 1.5, 3.0, 707.0, seed=5)
    guessed = fit.fit_keypoints(open_model, keypoints, camera=GUESS)
    r = fit.fit_keypoints(open_model, keypoints, camera=GUESS, estimate_focal=True)
    assert abs(np.log(r.camera.focal[0] / 707.0)) < 0.1, r.camera
    np.testing.assert_allclose(r.camera.focal[1], r.camera.focal[0])  # the aspect ratio is kept
    np.testing.assert_allclose(r.camera.center, GUESS.center)
    noise = np.linalg.norm(keypoints[..., :2] - exact, axis=-1).mean(1)
    assert np.all(r.reprojection_error < noise)

    def pa(result):
        return pa_mpjpe(j3, kp.convert(np.asarray(open_model(**result.params).joints), open_model, "coco17")[0]).mean()

    def depth(result):
        return np.abs(np.asarray(result.params["transl"])[:, 2] - params["transl"][:, 2]).mean()

    assert pa(r) < pa(guessed) and depth(r) < 0.3 * depth(guessed), (pa(r), pa(guessed), depth(r), depth(guessed))


def test_a_strong_prior_keeps_the_given_focal_length(open_model):
    _, keypoints, _, _ = _people(open_model, 2, 2.0, 3.0, 707.0, seed=3)
    r = fit.fit_keypoints(open_model, keypoints, camera=GUESS, estimate_focal=True, focal_prior=1e3)
    assert abs(np.log(r.camera.focal[0] / GUESS.focal[0])) < 0.01


def test_without_estimation_the_camera_is_the_given_one(open_model):
    _, keypoints, _, _ = _people(open_model, 1, 3.0, 4.0, 1000.0, seed=4)
    r = fit.fit_keypoints(open_model, keypoints, camera=CAMERA)
    assert r.camera is CAMERA
    with pytest.raises(ValueError, match="focal_prior"):
        fit.fit_keypoints(open_model, keypoints, camera=CAMERA, estimate_focal=True, focal_prior=-1.0)


# -- the command line ----------------------------------------------------------------------------------


def _openpose_folder(folder, model, frames=3):
    rng = np.random.default_rng(7)
    params = natural_poses(model, 1, rng)
    seq = {k: np.repeat(v, frames, 0) for k, v in params.items()}
    keypoints, _, _ = scene(model, seq, np.random.default_rng(0), convention="openpose25")
    return write_openpose(folder, keypoints)


def test_cli_keeps_the_image_diagonal_unless_asked_to_estimate(tmp_path, open_model):
    folder = _openpose_folder(tmp_path / "op", open_model)
    fixed, guessed, estimated = tmp_path / "fixed.npz", tmp_path / "guess.npz", tmp_path / "estimated.npz"
    assert main(["fit", str(folder), "-o", str(fixed), "--focal", "1000", "--center", "500,500"]) == 0
    assert main(["fit", str(folder), "-o", str(guessed), "--image-size", "1000,1000"]) == 0
    assert main(["fit", str(folder), "-o", str(estimated), "--image-size", "1000,1000", "--estimate-focal"]) == 0
    with np.load(fixed) as a, np.load(guessed) as b, np.load(estimated) as c:
        np.testing.assert_allclose(a["fit_focal"], 1000.0)
        np.testing.assert_allclose(b["fit_focal"], np.hypot(1000, 1000))  # the default: the diagonal, kept
        assert c["fit_focal"].shape == (3, 2) and np.all(c["fit_focal"] == c["fit_focal"][0, 0])  # one per sequence
        assert 700.0 < c["fit_focal"][0, 0] < 2900.0 and not np.isclose(c["fit_focal"][0, 0], np.hypot(1000, 1000))


def test_cli_priors_from_files(tmp_path, open_model, capsys):
    torch = pytest.importorskip("torch")  # noqa: F841 -- writes the fake checkpoint
    from fakes_vposer import reference, write_folder

    folder = _openpose_folder(tmp_path / "op", open_model, frames=2)
    vposer = write_folder(tmp_path / "V02_05", reference(seed=1))
    gmm = write_fake_gmm(tmp_path / "gmm_08.pkl")
    out = tmp_path / "fit.npz"
    argv = ["fit", str(folder), "-o", str(out), "--focal", "1000", "--center", "500,500"]
    assert main([*argv, "--vposer", str(vposer), "--gmm", str(gmm)]) == 0
    with np.load(out) as data:
        assert data["fit_error"].max() < 3.0
    assert main([*argv, "--vposer", str(tmp_path / "nowhere")]) == 2
    assert "--vposer" in capsys.readouterr().err
