"""fit.dense and fit.normal_matrix: the batched forward, the structured gradient and the Gauss–Newton matrix
equal pose_points' (whose dense Jacobian is the reference)."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.fit import dense
from smplcore.fit.body import FitBody, pose_points
from smplcore.fit.normal_matrix import normal_matrix

MODEL_TYPES = ["smpl", "smplh", "smplx", "mano", "flame", "open"]


def _model(fake_models, model_type):
    if model_type == "open":
        return smplcore.BodyModel(model_type="open", dtype=np.float64)
    return smplcore.BodyModel(fake_models["root"], model_type=model_type, dtype=np.float64)


@pytest.mark.parametrize("model_type", MODEL_TYPES)
def test_dense_products_match_pose_points(fake_models, model_type):
    body = FitBody.from_model(_model(fake_models, model_type))
    rng = np.random.default_rng(0)
    ids = np.sort(rng.choice(body.num_vertices + body.num_joints, 80, replace=False))
    pts = body.points(ids)
    theta = rng.normal(0, 0.4, (3, body.num_joints, 3))
    coeffs, transl = rng.normal(0, 1, (3, body.num_coeffs)), rng.normal(0, 1, (3, 3))
    lin = pose_points(body, pts, theta, coeffs, transl, jacobian=True)
    arrays = dense.dense_points(body, pts)
    posed = dense.pose(body, arrays, theta, coeffs, transl)
    np.testing.assert_allclose(np.moveaxis(posed.points, -1, 0), lin.points, atol=1e-12)
    residual = rng.normal(0, 1, posed.points.shape)
    expected = np.einsum("bncp,ncb->bp", lin.jacobian, residual)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(dense.gradient(body, arrays, posed, residual), expected, atol=1e-12 * scale)
    nj3, k = 3 * body.num_joints, body.num_coeffs
    coeff_jac = lin.jacobian[..., nj3 : nj3 + k]  # (B, n, 3, K)
    np.testing.assert_allclose(dense.coefficient_jacobian_by_body(arrays, posed), coeff_jac, atol=1e-12)
    batch_last = dense.coefficient_jacobian(body, pts, arrays, posed)  # (n, 3, K, B)
    np.testing.assert_allclose(np.moveaxis(batch_last, -1, 0), coeff_jac, atol=1e-12)
    weights = rng.uniform(0, 2, (3, len(ids)))
    jac = lin.jacobian.reshape(3, -1, lin.jacobian.shape[-1]) * np.sqrt(np.repeat(weights, 3, axis=1))[..., None]
    expected = np.swapaxes(jac, 1, 2) @ jac
    matrix = normal_matrix(body, pts, arrays, posed, weights)
    np.testing.assert_allclose(matrix, expected, atol=1e-12 * np.abs(expected).max())


def test_float32_products_stay_close(fake_models):
    body = FitBody.from_model(_model(fake_models, "smpl"))
    rng = np.random.default_rng(1)
    pts = body.points(np.arange(body.num_vertices))
    theta = rng.normal(0, 0.4, (2, body.num_joints, 3))
    coeffs, transl = rng.normal(0, 1, (2, body.num_coeffs)), rng.normal(0, 1, (2, 3))
    exact = dense.pose(body, dense.dense_points(body, pts), theta, coeffs, transl).points
    single = dense.pose(body, dense.dense_points(body, pts, np.float32), theta, coeffs, transl).points
    assert single.dtype == np.float32
    assert np.abs(single - exact).max() < 1e-5  # metres: float32 resolution of a posed mesh


def test_normal_matrix_of_chosen_columns(fake_models):
    body = FitBody.from_model(_model(fake_models, "smplx"))
    rng = np.random.default_rng(3)
    ids = np.sort(rng.choice(body.num_vertices, 120, replace=False))
    pts = body.points(ids)
    theta = rng.normal(0, 0.4, (2, body.num_joints, 3))
    coeffs, transl = rng.normal(0, 1, (2, body.num_coeffs)), rng.normal(0, 1, (2, 3))
    arrays = dense.dense_points(body, pts)
    posed = dense.pose(body, arrays, theta, coeffs, transl)
    weights = rng.uniform(0, 1, (2, len(ids)))
    full = normal_matrix(body, pts, arrays, posed, weights)
    columns = np.sort(rng.choice(full.shape[1], 40, replace=False))  # pose, shape and translation mixed
    np.testing.assert_allclose(
        normal_matrix(body, pts, arrays, posed, weights, columns), full[:, columns[:, None], columns], rtol=1e-12
    )


def test_kinematics_slopes_are_the_derivatives_of_the_features(fake_models):
    from smplcore.engine import rodrigues
    from smplcore.fit.kinematics import kinematics

    body = FitBody.from_model(_model(fake_models, "smpl"))
    rng = np.random.default_rng(4)
    theta = rng.normal(0, 0.5, (2, body.num_joints, 3))
    kin = kinematics(body, theta, np.zeros((2, body.num_coeffs)))
    step = 1e-6
    for a in range(3):
        moved = theta.copy()
        moved[..., a] += step
        numeric = (rodrigues(moved[:, 1:]) - rodrigues(theta[:, 1:] - np.eye(3)[a] * step)) / (2 * step)
        np.testing.assert_allclose(kin.slopes[..., a], numeric.reshape(2, -1, 9), atol=1e-8)
