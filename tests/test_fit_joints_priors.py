"""fit_joints on targets the model cannot meet plausibly: joint limits, bones out of reach, missing markers,
a pose mixture plugged in (issue 25: a CMU torso is shorter than any body of the shape space, and the fit
folded the spine to reach the neck)."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore import fit
from smplcore.fit.bones import BoneLengthWarning
from smplcore.fit.plausibility import ImplausibleFitWarning
from smplcore.fit.priors import GMMPrior, joint_limits

# the joints of a mocap skeleton mapped to the model: no spine joints
NAMES = [
    "pelvis", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "neck", "head",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
]  # fmt: skip
UPPER = {"neck", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist"}


@pytest.fixture(scope="module")
def model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def _natural(model, batch, seed=0):
    """Poses inside the limits: small random bends, elbows and knees flexed."""
    rng = np.random.default_rng(seed)
    lo, hi = joint_limits(model.joint_names[1:24])
    pose = np.clip(rng.normal(0, 0.15, (batch, 69)), lo.reshape(-1) + 0.03, hi.reshape(-1) - 0.03)
    pose[:, 57:] = 0.0
    return {
        "body_pose": pose,
        "global_orient": rng.normal(0, 0.3, (batch, 3)),
        "transl": rng.normal(0, 0.3, (batch, 3)),
    }


def _targets(model, params, names=NAMES):
    out = model(**params)
    return out.joints[:, [model.joint_names.index(n) for n in names]].copy()


def _short_torso(model, batch=3, drop=0.18):
    """The model's own joints with the upper body moved down its spine by ``drop`` metres."""
    params = _natural(model, batch)
    target = _targets(model, params)
    out = model(**params)
    up = out.joints[:, model.joint_names.index("neck")] - out.joints[:, 0]
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    for i, n in enumerate(NAMES):
        if n in UPPER:
            target[:, i] -= drop * up
    return target


def _spine(model, result):
    pose = np.asarray(result.params["body_pose"]).reshape(-1, 23, 3)
    return {n: np.degrees(pose[:, model.joint_names.index(n) - 1]) for n in ("spine1", "spine2", "spine3", "neck")}


def test_a_short_torso_folds_the_spine_without_limits(model):
    with pytest.warns(ImplausibleFitWarning, match="spine"):
        r = fit.fit_joints(model, _short_torso(model), joint_names=NAMES, joint_limits=0.0, gmm=None)
    bend = sum(np.abs(a[:, 0]) for a in _spine(model, r).values())
    assert bend.min() > 60  # the spine and neck fold to bring the neck 18 cm down
    assert not r.plausible.any()


def test_the_limits_keep_a_short_torso_plausible_and_the_fit_names_the_bones(model):
    with pytest.warns(BoneLengthWarning, match="pelvis-neck"):
        r = fit.fit_joints(model, _short_torso(model), joint_names=NAMES)
    assert r.plausible.all()
    spine3 = _spine(model, r)["spine3"]
    assert spine3[:, 0].max() < 80 / 3 + 5  # its forward range, 26.7°, and a few degrees of softness
    assert ("pelvis", "neck") in r.bones.out_of_reach
    i = r.bones.bones.index(("pelvis", "neck"))
    rest = model().joints[0]
    assert r.bones.target[i] == pytest.approx(np.linalg.norm(rest[12] - rest[0]) - 0.18, abs=0.03)
    assert r.bones.beyond[i] < -0.05  # shorter than any body of the shape space
    assert "pelvis -> neck" in str(r.bones) and "OUT OF REACH" in str(r.bones)
    i = NAMES.index("neck")
    assert np.nanmin(r.point_error[:, i]) > 0.01  # the neck is missed, not met by folding


def test_reachable_bones_are_not_reported(model, recwarn):
    r = fit.fit_joints(model, _targets(model, _natural(model, 2)), joint_names=NAMES)
    assert r.bones.out_of_reach == []
    shin = r.bones.bones.index(("left_knee", "left_ankle"))
    assert abs(r.bones.off[shin]) < 2e-3  # a rigid bone of the model's own shape: met
    assert not [w for w in recwarn if issubclass(w.category, (BoneLengthWarning, ImplausibleFitWarning))]


def test_missing_markers_are_masked_not_refused(model):
    params = _natural(model, 4, seed=2)
    target = _targets(model, params)
    missing = target.copy()
    missing[1, NAMES.index("left_elbow")] = np.nan
    missing[2, NAMES.index("right_knee"), 0] = np.nan  # one coordinate lost: the joint is missing
    missing[2, NAMES.index("head")] = np.nan
    r = fit.fit_joints(model, missing, joint_names=NAMES)
    assert r.mask.sum() == 4 * len(NAMES) - 3
    assert not r.mask[1, NAMES.index("left_elbow")] and not r.mask[2, NAMES.index("right_knee")]
    assert np.isnan(r.point_error[~r.mask]).all() and np.isfinite(r.point_error[r.mask]).all()
    assert r.joint_error.max() < 0.005
    # the missing joints land where they were (the others hold them)
    fitted = _targets(model, {k: np.asarray(v) for k, v in r.params.items()})
    assert np.linalg.norm(fitted[~r.mask] - target[~r.mask], axis=-1).max() < 0.05
    # as zero weights do
    weights = r.mask.astype(float)
    w = fit.fit_joints(model, np.where(r.mask[..., None], target, 0.0), joint_names=NAMES, joint_weights=weights)
    np.testing.assert_allclose(w.joint_error, r.joint_error, atol=1e-9)


def test_too_few_markers_in_a_frame_name_the_frame(model):
    target = _targets(model, _natural(model, 3))
    target[2, 2:] = np.nan
    with pytest.raises(ValueError, match=r"bodies \[2\] .*fewer than 3 joints"):
        fit.fit_joints(model, target, joint_names=NAMES)


def test_a_gaussian_mixture_plugs_in_and_pulls_towards_its_mean(model):
    target = _short_torso(model, batch=2)
    mean = np.zeros((1, 69))
    gmm = GMMPrior.from_arrays(mean, np.eye(69)[None] * 0.05**2, np.ones(1))
    with pytest.warns(BoneLengthWarning):
        plain = fit.fit_joints(model, target, joint_names=NAMES)
        pulled = fit.fit_joints(model, target, joint_names=NAMES, gmm=gmm, gmm_weight=1e-3)
    assert np.abs(pulled.params["body_pose"]).sum() < 0.8 * np.abs(plain.params["body_pose"]).sum()
    with pytest.raises(TypeError, match="gmm"):
        fit.fit_joints(model, target, joint_names=NAMES, gmm=3)


def test_auto_takes_the_open_mixture_only_where_bones_are_out_of_reach(model, monkeypatch):
    calls = []

    def open_prior(cls):
        calls.append(1)
        return GMMPrior.from_arrays(np.zeros((1, 69)), np.eye(69)[None] * 0.05**2, np.ones(1))

    monkeypatch.setattr(GMMPrior, "open", classmethod(open_prior), raising=False)
    reachable = _targets(model, _natural(model, 2))
    auto = fit.fit_joints(model, reachable, joint_names=NAMES)
    none = fit.fit_joints(model, reachable, joint_names=NAMES, gmm=None)
    assert not calls
    np.testing.assert_allclose(auto.params["body_pose"], none.params["body_pose"])
    short = _short_torso(model, batch=2)
    with pytest.warns(BoneLengthWarning):
        auto = fit.fit_joints(model, short, joint_names=NAMES)
        none = fit.fit_joints(model, short, joint_names=NAMES, gmm=None)
    assert calls
    bend = {
        k: sum(np.abs(a[:, 0]) for a in _spine(model, r).values()).mean() for k, r in (("auto", auto), ("none", none))
    }
    assert bend["auto"] < 0.7 * bend["none"]  # the spine and neck stay nearer the mixture's upright mean
    assert auto.plausible.all()
