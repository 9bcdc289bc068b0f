"""Honest fit results: per-point errors and the mask used, joints outside their anatomical limits, warnings,
and a ``converged`` that means the optimiser converged."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore import fit
from smplcore.errors import ShapeError
from smplcore.fit.plausibility import TOLERANCE, ImplausibleFitWarning, assess
from smplcore.fit.priors import JOINT_LIMITS


@pytest.fixture(scope="module")
def model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def _body_index(model, name):
    return model.joint_names.index(name) - 1  # body_pose starts after the pelvis


def test_a_rest_pose_is_plausible(model):
    p = assess(model, np.zeros((3, 69)))
    assert p.plausible.tolist() == [True, True, True]
    assert p.excess.shape == (3, 23, 3) and not p.excess.any()
    assert p.violations(0) == []
    assert "3 of 3 bodies within" in p.summary()


def test_excess_is_measured_in_degrees_per_joint_and_axis(model):
    pose = np.zeros((2, 69))
    spine3 = _body_index(model, "spine3")
    pose[1, spine3 * 3] = np.radians(60.0)  # forward bend; the range is 80/3 = 26.7 degrees
    knee = _body_index(model, "right_knee")
    pose[1, knee * 3] = np.radians(-4.0)  # hyperextension inside the tolerance
    p = assess(model, pose)
    assert p.excess[1, spine3, 0] == pytest.approx(60.0 - 80 / 3)
    assert p.excess[1, knee, 0] == pytest.approx(4.0)
    assert p.plausible.tolist() == [True, False]
    assert p.violations(1) == [("spine3", "x", 33.3)]
    assert p.violations(1, tolerance=0.0) == [("spine3", "x", 33.3), ("right_knee", "x", 4.0)]
    assert p.joint_counts() == {"spine3": 1}
    assert "1 of 2 bodies" in p.summary() and "spine3" in p.summary()


def test_right_side_limits_mirror_the_left(model):
    lo, hi = np.radians(JOINT_LIMITS["left_shoulder"][0][2])  # z: abduction past the T-pose is negative
    pose = np.zeros((2, 69))
    pose[0, _body_index(model, "left_shoulder") * 3 + 2] = lo - np.radians(20)
    pose[1, _body_index(model, "right_shoulder") * 3 + 2] = -(lo - np.radians(20))
    p = assess(model, pose)
    assert p.violations(0) == [("left_shoulder", "z", 20.0)]
    assert p.violations(1) == [("right_shoulder", "z", 20.0)]


def test_assess_takes_names_and_one_body_and_refuses_a_wrong_width(model):
    names = ["spine1", "neck"]
    p = assess(names, np.radians([0, 0, 0, 50.0, 0, 0]))
    assert p.excess.shape == (1, 2, 3) and p.violations(0) == [("neck", "x", 27.5)]
    with pytest.raises(ShapeError, match="body_pose"):
        assess(model, np.zeros((1, 63)))
    assert TOLERANCE > 0


def test_fit_joints_reports_point_errors_and_the_mask(model):
    target = model(body_pose=np.full((2, 69), 0.1)).joints[:, :22].copy()
    weights = np.ones(22)
    weights[5] = 0.0
    target[:, 5] += 0.2  # the unused joint is far off
    r = fit.fit_joints(model, target, joint_weights=weights)
    assert r.mask.shape == (2, 22) and not r.mask[:, 5].any() and r.mask.sum() == 42
    assert np.isnan(r.point_error[:, 5]).all() and np.isfinite(r.point_error[r.mask]).all()
    np.testing.assert_allclose(np.nanmean(r.point_error, axis=1), r.joint_error)
    fitted = model(**r.params).joints[:, :22]
    np.testing.assert_allclose(np.linalg.norm(fitted - target, axis=-1)[:, :5], r.point_error[:, :5], atol=1e-9)
    assert r.plausible.all() and "plausible=2/2" in repr(r)


def test_fit_vertices_reports_point_errors_and_plausibility(model):
    target = model(body_pose=np.full((1, 69), 0.1)).vertices
    r = fit.fit_vertices(model, target)
    assert r.point_error.shape == target.shape[:2] and r.mask.all()
    np.testing.assert_allclose(r.point_error.mean(1), r.vertex_error, rtol=1e-6)
    assert r.plausible.tolist() == [True]


def test_converged_is_false_when_the_iterations_run_out(model):
    rng = np.random.default_rng(4)
    target = model(body_pose=rng.normal(0, 0.2, (3, 69))).joints[:, :22]
    short = fit.fit_joints(model, target, max_iter=1, tol=1e-12, joint_limits=0.0, share_betas=False)
    assert short.iterations == 1 and not short.converged.any()
    shared = fit.fit_joints(model, target, max_iter=1, tol=1e-12, joint_limits=0.0, share_betas=True)
    assert not shared.converged.any()
    full = fit.fit_joints(model, target, max_iter=50, tol=1e-6, joint_limits=0.0)
    assert full.converged.all() and full.iterations < 50


def test_an_implausible_fit_warns_naming_the_bodies_and_joints(model):
    pose = np.zeros((2, 69))
    pose[1, _body_index(model, "spine3") * 3] = np.radians(90.0)
    target = model(body_pose=pose).joints[:, :22]
    with pytest.warns(ImplausibleFitWarning, match=r"1 of 2 bodies .*spine3"):
        r = fit.fit_joints(model, target, pose_prior=1e-9, joint_limits=0.0)
    assert r.plausible.tolist() == [True, False]
    assert r.plausibility.violations(1)[0][:2] == ("spine3", "x")
    assert r.joint_error.max() < 1e-3  # without limits the target's own folded spine is met


def test_the_limits_keep_a_folded_spine_plausible_and_quiet(model, recwarn):
    pose = np.zeros((2, 69))
    pose[1, _body_index(model, "spine3") * 3] = np.radians(90.0)
    target = model(body_pose=pose).joints[:, :22]
    r = fit.fit_joints(model, target, share_betas=False)
    assert r.plausible.all() and r.plausibility.worst.max() < 5.0
    assert not [w for w in recwarn if issubclass(w.category, ImplausibleFitWarning)]
    assert r.joint_error[0] < 1e-3 and r.point_error[1].max() > 0.02  # the folded body's head is missed


def test_fit_vertices_keeps_limits_only_when_asked(model):
    pose = np.zeros((1, 69))
    pose[0, _body_index(model, "left_elbow") * 3 + 1] = np.radians(40.0)  # bent backwards 35° past its 5°
    target = model(body_pose=pose).vertices
    faithful = fit.fit_vertices(model, target)
    assert faithful.vertex_error[0] < 1e-4 and faithful.plausible.tolist() == [False]
    limited = fit.fit_vertices(model, target, joint_limits=100.0)  # against 6,890 vertices' squared distances
    assert limited.plausible.tolist() == [True] and limited.vertex_error[0] > 1e-3
