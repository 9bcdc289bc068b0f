"""fit_joints on sequences: one shape for one person by default, a temporal term solved as one coupled system
(no oscillation between frames), rotations continuous along the sequence."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore import fit
from smplcore.engine import rodrigues
from smplcore.fit.body import FitBody
from smplcore.fit.priors import joint_limits
from smplcore.fit.temporal import Temporal, temporal_step, unwrap_rotations


@pytest.fixture(scope="module")
def model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def _walk(model, frames=40, seed=0, turned=np.pi):
    """A smooth sequence of one person inside the joint limits, facing about ``turned`` radians round y."""
    rng = np.random.default_rng(seed)
    lo, hi = joint_limits(model.joint_names[1:24])
    base = np.clip(rng.normal(0, 0.15, 69), lo.reshape(-1) + 0.05, hi.reshape(-1) - 0.05)
    t = np.linspace(0, 1, frames)[:, None]
    pose = np.clip(base * (1 + 0.5 * np.sin(4 * t)), lo.reshape(-1), hi.reshape(-1))
    pose[:, 57:] = 0
    orient = np.zeros((frames, 3))
    orient[:, 1] = turned + 0.2 * np.sin(3 * t[:, 0])  # crosses 180°: two axis-angle vectors per rotation
    return {
        "body_pose": pose,
        "global_orient": orient,
        "betas": np.repeat(rng.normal(0, 1, (1, 10)), frames, 0),
        "transl": t * np.array([1.0, 0.0, 0.3]),
    }


def _jitter(points):
    """Mean |second difference| (metres per frame²) of (T, n, 3) points."""
    return np.linalg.norm(points[2:] - 2 * points[1:-1] + points[:-2], axis=-1).mean()


def test_the_coupled_step_is_the_exact_solution_of_the_block_system():
    rng = np.random.default_rng(0)
    batch, size = 7, 6
    a = rng.normal(size=(batch, size, size))
    hess = a @ np.swapaxes(a, 1, 2) + np.eye(size)
    grad = rng.normal(size=(batch, size))
    shared = np.array([0, 0, 0, 0, 1, 1], bool)
    coupling = np.array([0.3, 0.5, 0.0, 0.2, 0.0, 0.0])
    damping = np.full(batch, 0.1)
    step = temporal_step(hess.copy(), grad, damping, shared, coupling)
    # the same system written out densely: per-body blocks, the shared columns once, the chain's Laplacian
    loc, sh = np.flatnonzero(~shared), np.flatnonzero(shared)
    index = np.zeros((batch, size), int)
    index[:, loc] = np.arange(batch)[:, None] * len(loc) + np.arange(len(loc))
    index[:, sh] = batch * len(loc) + np.arange(len(sh))
    n = batch * len(loc) + len(sh)
    dense, rhs = np.zeros((n, n)), np.zeros(n)
    for b in range(batch):
        damped = hess[b] + np.diag(0.1 * (np.diag(hess[b]) + 1e-9))
        np.add.at(dense, (index[b][:, None], index[b][None, :]), damped)
        np.add.at(rhs, index[b], grad[b])
    for b in range(batch - 1):
        for p in loc:
            i, j = index[b, p], index[b + 1, p]
            dense[i, i] += coupling[p]
            dense[j, j] += coupling[p]
            dense[i, j] -= coupling[p]
            dense[j, i] -= coupling[p]
    expected = -np.linalg.solve(dense, rhs)[index]
    np.testing.assert_allclose(step, expected, atol=1e-12)


def test_the_temporal_gradient_is_the_cost_s():
    rng = np.random.default_rng(1)
    term = Temporal(0.3, np.array([0, 2]))
    x = rng.normal(size=(5, 4))
    cost, grad = term.cost_gradient(x)
    eps = 1e-6
    for b, c in [(0, 0), (2, 2), (4, 0), (3, 1)]:
        d = np.zeros_like(x)
        d[b, c] = eps
        numeric = (term.cost(x + d).sum() - term.cost(x - d).sum()) / (2 * eps)
        assert 0.5 * numeric == pytest.approx(grad[b, c], abs=1e-6)  # the half-gradient convention


def test_unwrapping_keeps_the_rotations_and_makes_them_continuous(model):
    body = FitBody.from_model(model)
    angle = np.pi + np.linspace(-0.3, 0.3, 9)
    pose = np.zeros((9, body.num_pose))
    pose[:, 1] = np.where(angle > np.pi, angle - 2 * np.pi, angle)  # what a per-frame log returns
    out = unwrap_rotations(body, pose)
    np.testing.assert_allclose(out[:, 1], angle, atol=1e-12)
    np.testing.assert_allclose(rodrigues(out[:, :3]), rodrigues(pose[:, :3]), atol=1e-12)


def test_one_person_shares_betas_by_default_and_different_people_do_not(model):
    params = _walk(model, frames=6)
    target = model(**params).joints[:, :22]
    one = fit.fit_joints(model, target)
    np.testing.assert_allclose(one.params["betas"], np.repeat(one.params["betas"][:1], 6, 0), atol=1e-12)
    people = dict(params, betas=np.random.default_rng(3).normal(0, 1, (6, 10)))
    many = fit.fit_joints(model, model(**people).joints[:, :22])
    assert np.ptp(many.params["betas"][:, 0]) > 0.1
    forced = fit.fit_joints(model, target, share_betas=False)
    assert np.ptp(forced.params["betas"][:, 0]) > 0


def test_smoothness_removes_noise_without_oscillating(model):
    params = _walk(model)
    clean = model(**params).joints[:, :22]
    noisy = clean + np.random.default_rng(5).normal(0, 0.01, clean.shape)
    rough = fit.fit_joints(model, noisy)
    smooth = fit.fit_joints(model, noisy, smoothness=1.0)
    fitted = {name: model(**r.params).joints[:, :22] for name, r in (("rough", rough), ("smooth", smooth))}
    assert _jitter(fitted["smooth"]) < 0.4 * _jitter(fitted["rough"])
    # the pelvis does not swing between frames (it did with rounds of neighbour priors near 180°)
    hips = fitted["smooth"][:, 1:3]
    assert np.linalg.norm(np.diff(hips, axis=0), axis=-1).max() < 0.06
    error = {k: np.linalg.norm(v - clean, axis=-1).mean() for k, v in fitted.items()}
    assert error["smooth"] < 0.7 * error["rough"]  # nearer the noise-free motion
    assert smooth.converged.all()


def test_smoothing_is_relative_to_the_joints_so_one_weight_serves_rotation_and_translation(model):
    params = _walk(model, frames=12)
    target = model(**params).joints[:, :22]
    shaken = target + np.where(np.arange(12) % 2, 0.02, -0.02)[:, None, None]  # the whole body jumps 4 cm
    r = fit.fit_joints(model, shaken, smoothness=3.0)
    step = np.abs(np.diff(np.asarray(r.params["transl"])[:, 1]))
    assert step.max() < 0.02  # the alternating jump is mostly smoothed away
