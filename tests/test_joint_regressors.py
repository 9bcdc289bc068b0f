"""The ``joint_regressors`` model option: extra regressed points appended to the output joints under their
convention's names, equal on every path (mesh, joints only, autograd, reference kernel) to the regressor
applied to the posed vertices."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.errors import ModelFileError
from smplcore.keypoints import Regressor, names

torch = pytest.importorskip("torch")


def _h36m_like(path, num_vertices, seed=0):
    rng = np.random.default_rng(seed)
    matrix = np.where(rng.random((17, num_vertices)) < 0.003, rng.random((17, num_vertices)), 0.0)
    matrix /= matrix.sum(axis=1, keepdims=True)
    np.save(path, matrix)  # as SPIN ships J_regressor_h36m.npy: dense (17, V)
    return matrix


def test_regressed_points_are_appended_on_every_path(fake_models, tmp_path):
    matrix = _h36m_like(tmp_path / "J_regressor_h36m.npy", 6890)
    model = smplcore.create(
        fake_models["smpl_neutral_pkl"], joint_regressors={"h36m17": tmp_path / "J_regressor_h36m.npy"}
    )
    assert model.joint_names[45:] == [f"h36m17:{n}" for n in names("h36m17")]
    gen = torch.Generator().manual_seed(0)
    params = {
        "body_pose": 0.4 * torch.randn(3, 69, generator=gen),
        "betas": torch.randn(3, 10, generator=gen),
        "transl": torch.randn(3, 3, generator=gen),
    }
    with torch.no_grad():
        full = model(**params)
        joints_only = model(return_verts=False, **params)
        plain = model(kernel="reference", **params)
    grad = model(**{k: v.clone().requires_grad_(True) for k, v in params.items()})
    expected = np.einsum("kv,bvd->bkd", matrix, full.vertices.numpy())
    for out in (full, joints_only, plain, grad):
        assert out.joints.shape == (3, 45 + 17, 3)
        np.testing.assert_allclose(out.joints[:, 45:].detach().numpy(), expected, atol=2e-5)
    body = smplcore.BodyModel(
        fake_models["smpl_neutral_pkl"],
        joint_regressors={"h36m17": Regressor.load(tmp_path / "J_regressor_h36m.npy", convention="h36m17")},
    )
    out = body(**{k: v.numpy() for k, v in params.items()}, return_verts=False)
    np.testing.assert_allclose(out.joints[:, 45:], expected, atol=2e-5)


def test_a_regressor_for_another_mesh_is_a_clear_error(fake_models, tmp_path):
    _h36m_like(tmp_path / "J_regressor_h36m.npy", 10475)
    with pytest.raises(ModelFileError, match="J_regressor_h36m.npy"):
        smplcore.BodyModel(
            fake_models["smpl_neutral_pkl"], joint_regressors={"h36m17": tmp_path / "J_regressor_h36m.npy"}
        )


def test_the_open_model_ships_its_own_regressors():
    body = smplcore.BodyModel(model_type="open", joint_regressors={"coco17": "open", "h36m17": "open"})
    assert len(body.joint_names) == 45 + 17 + 17
    assert body(return_verts=False).joints.shape == (1, 79, 3)
