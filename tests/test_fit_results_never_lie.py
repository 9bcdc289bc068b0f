"""A fit never returns a result it did not find (issue 27, item 5): no NaN / inf parameter or error comes
back (an error is raised instead), targets in the wrong units are refused, and bodies left far from their
targets are flagged not converged with a warning."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore import fit
from smplcore.fit.checks import FitError, finite_result
from smplcore.fit.priors import joint_limits


@pytest.fixture(scope="module")
def model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def _joints(model, batch=2):
    rng = np.random.default_rng(0)
    lo, hi = joint_limits(model.joint_names[1:24])  # a pose inside the anatomical limits (fit_joints keeps them)
    pose = np.clip(rng.normal(0, 0.2, (batch, 69)), lo.reshape(-1) + 0.02, hi.reshape(-1) - 0.02)
    return model(body_pose=pose).joints[:, :22]


def _keypoints(model):
    from smplcore import keypoints as kp

    out = model(global_orient=np.array([[np.pi, 0, 0]]), transl=np.array([[0.0, 0.3, 4.0]]))
    pts, _ = kp.convert(out.joints, model, "coco17")
    uv = fit.Camera(focal=1000.0, center=(320.0, 240.0)).project(pts)
    return np.concatenate([uv, np.ones((*uv.shape[:-1], 1))], axis=-1)


def test_min_points_zero_is_refused_not_a_nan_translation(model):
    cam = fit.Camera(focal=1000.0, center=(320.0, 240.0))
    with pytest.raises(ValueError, match="min_points"):
        fit.fit_keypoints(model, np.zeros((1, 17, 3)), "coco17", cam, min_points=0)


def test_a_huge_focal_length_is_refused(model):
    with pytest.raises(ValueError, match="focal"):
        fit.Camera(focal=1e300, center=(320.0, 240.0))


def test_joints_in_millimetres_are_refused_naming_the_unit(model):
    with pytest.raises(ValueError, match="joints: .*millimetres"):
        fit.fit_joints(model, _joints(model) * 1000)


def test_vertices_in_centimetres_are_refused(model):
    target = model(betas=np.ones((1, 10))).vertices * 100
    with pytest.raises(ValueError, match="vertices: .*centimetres"):
        fit.fit_vertices(model, target)


def test_keypoints_a_million_pixels_off_are_flagged_not_converged(model):
    cam = fit.Camera(focal=1000.0, center=(320.0, 240.0))
    with pytest.warns(UserWarning, match="flagged not converged"):
        r = fit.fit_keypoints(model, _keypoints(model) + [1e6, 0, 0], "coco17", cam, multi_start=False, max_iter=5)
    assert not r.converged.any()
    assert np.isfinite(r.reprojection_error).all()


def test_a_clean_fit_is_not_flagged(model, recwarn):
    r = fit.fit_joints(model, _joints(model))
    assert r.converged.all() and r.joint_error.max() < 0.005
    assert not [w for w in recwarn if "flagged" in str(w.message)]


def test_joints_far_from_the_origin_fit_exactly_in_float64(model):
    target = _joints(model) + np.array([1e6, 0.0, -1e6])
    r = fit.fit_joints(model, target)
    assert r.joint_error.max() < 0.005 and r.converged.all()


def test_a_non_finite_fit_raises_instead_of_returning(model):
    r = fit.fit_joints(model, _joints(model))
    r.params["transl"] = np.array(r.params["transl"])
    r.params["transl"][1, 0] = np.nan
    with pytest.raises(FitError, match=r"bodies \[1\]"):
        finite_result(r, "fit_joints")


@pytest.mark.parametrize("option", ["shape_prior", "pose_prior", "smoothness"])
@pytest.mark.parametrize("value", [np.nan, np.inf, -1.0])
def test_nan_or_negative_weights_do_not_switch_priors_off(model, option, value):
    with pytest.raises(ValueError, match=option):
        fit.fit_joints(model, _joints(model), **{option: value})


@pytest.mark.parametrize("anneal", [(), (np.nan,), (-1.0,)])
def test_anneal_must_hold_finite_non_negative_multipliers(model, anneal):
    cam = fit.Camera(focal=1000.0, center=(320.0, 240.0))
    with pytest.raises(ValueError, match="anneal"):
        fit.fit_keypoints(model, _keypoints(model), "coco17", cam, anneal=anneal)
