"""fit.rotations: the vectorised Kabsch rotation equals the SVD's on every kind of moment matrix."""

from __future__ import annotations

import numpy as np

from smplcore.fit.rotations import nearest_rotations, rotation_log


def _svd_kabsch(moments):
    u, sing, vt = np.linalg.svd(moments)
    sign = np.sign(np.linalg.det(u @ vt))
    u[..., :, 2] *= sign[..., None]
    return u @ vt, sing[..., 1]


def test_polar_iteration_equals_the_svd():
    rng = np.random.default_rng(0)
    count = 400
    rot, _ = np.linalg.qr(rng.normal(size=(count, 3, 3)))
    rot *= np.sign(np.linalg.det(rot))[:, None, None]
    spread = rng.normal(size=(count, 3, 6))
    moments = rot @ (spread @ np.swapaxes(spread, 1, 2)) * rng.uniform(1e-3, 10, (count, 1, 1))
    moments[:20, :, 2] *= 1e-6  # flat point sets: to the SVD
    moments[20:30] *= -1  # negative determinants: the smallest direction flips
    moments[30:35] = 0.0  # no points at all
    got, middle = nearest_rotations(moments)
    want, want_middle = _svd_kabsch(moments.copy())
    np.testing.assert_allclose(got[35:], want[35:], atol=1e-10)
    np.testing.assert_allclose(middle, want_middle, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got @ np.swapaxes(got, 1, 2), np.broadcast_to(np.eye(3), got.shape), atol=1e-12)
    assert np.all(np.linalg.det(got) > 0.999999)


def test_keeps_the_leading_shape():
    moments = np.random.default_rng(1).normal(size=(2, 5, 3, 3))
    rot, middle = nearest_rotations(moments)
    assert rot.shape == (2, 5, 3, 3) and middle.shape == (2, 5)


def test_rotation_log_of_a_half_turn_and_of_the_identity():
    rotvec = np.array([[0.0, 0.0, 0.0], [np.pi, 0.0, 0.0], [0.3, -0.2, 0.1]])
    from scipy.spatial.transform import Rotation

    got = rotation_log(Rotation.from_rotvec(rotvec).as_matrix())
    np.testing.assert_allclose(np.abs(got), np.abs(rotvec), atol=1e-12)


def test_rotation_log_inverts_the_exponential_near_zero_and_half_turns():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(2)
    axes = rng.normal(size=(300, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([rng.uniform(0, np.pi, 100), rng.uniform(0, 1e-8, 100), np.pi - rng.uniform(0, 1e-7, 100)])
    rotvec = axes * angles[:, None]
    matrices = Rotation.from_rotvec(rotvec).as_matrix()
    got = rotation_log(matrices.reshape(3, 100, 3, 3)).reshape(-1, 3)
    np.testing.assert_allclose(Rotation.from_rotvec(got).as_matrix(), matrices, atol=1e-12)
    assert np.all(np.linalg.norm(got, axis=1) <= np.pi + 1e-12)
    np.testing.assert_allclose(got[:200], rotvec[:200], atol=1e-12)  # below a half turn: the same vector
    single = rotation_log(matrices[:50].astype(np.float32))  # float32 in, no warnings, float32 accuracy
    np.testing.assert_allclose(Rotation.from_rotvec(single).as_matrix(), matrices[:50], atol=2e-6)
