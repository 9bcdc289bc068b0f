"""Forward inputs: only the documented layouts, NaN/inf refused by default, rotation checks, scalars, sparse
and grad tensors, batch 0 — each a clear error naming the argument, or an empty output of the right shape."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.errors import ShapeError

torch = pytest.importorskip("torch")


@pytest.fixture(scope="module")
def models():
    return smplcore.create(model_type="open"), smplcore.BodyModel(model_type="open")


@pytest.mark.parametrize(
    "name,shape", [("body_pose", (2, 3, 23)), ("body_pose", (2, 69, 1)), ("betas", (2, 2, 5)), ("transl", (2, 3, 1))]
)
def test_only_documented_layouts_are_accepted(models, name, shape):
    for model, make in ((models[0], torch.zeros), (models[1], np.zeros)):
        with pytest.raises(ShapeError, match=rf"^{name}: expected shape"):
            model(**{name: make(shape)})


def test_the_other_documented_layouts_work(models):
    module, body = models
    aa = np.random.default_rng(0).normal(0, 0.3, (2, 23, 3))
    a = body(body_pose=aa).vertices
    np.testing.assert_allclose(body(body_pose=aa.reshape(2, 69)).vertices, a)
    with torch.no_grad():
        np.testing.assert_allclose(
            module(body_pose=torch.tensor(aa, dtype=torch.float32)).vertices.numpy(), a, atol=1e-5
        )


def test_a_72_value_pose_says_how_to_split_it(models):
    with pytest.raises(ShapeError, match=r"72 = global_orient \(3\) \+ body_pose \(69\)"):
        models[1](body_pose=np.zeros((1, 72)))


def test_non_finite_inputs_are_refused_by_default_naming_the_index(models):
    pose = np.zeros((3, 69))
    pose[2, 7] = np.nan
    for model, make in ((models[0], torch.tensor), (models[1], np.asarray)):
        with pytest.raises(ValueError, match=r"body_pose: non-finite value .* at index \(2, 7\)"):
            model(body_pose=make(pose, dtype=np.float32) if make is np.asarray else make(pose, dtype=torch.float32))
    out = models[1].__class__(model_type="open", check_finite=False)(body_pose=pose)
    assert np.isnan(out.vertices[2]).any() and np.isfinite(out.vertices[0]).all()
    with torch.no_grad():
        assert torch.isnan(
            models[0](body_pose=torch.tensor(pose, dtype=torch.float32), check_finite=False).vertices
        ).any()


@pytest.mark.parametrize("matrix", [np.zeros((3, 3)), 2 * np.eye(3), np.diag([1.0, 1.0, -1.0])])
def test_rotation_matrices_are_checked_in_numpy_and_on_request_in_torch(models, matrix):
    mats = np.broadcast_to(matrix, (1, 23, 3, 3)).copy()
    with pytest.raises(ValueError, match=r"body_pose: the matrix at index \(0, 0\) is not a rotation"):
        models[1](body_pose=mats, pose2rot=False)
    t = torch.tensor(mats, dtype=torch.float32)
    with torch.no_grad():
        models[0](body_pose=t, pose2rot=False)  # as smplx: not checked by default
        with pytest.raises(ValueError, match="not a rotation"):
            models[0](body_pose=t, pose2rot=False, check_rotations=True)


def test_scalars_sparse_and_grad_tensors_get_clear_errors(models):
    module, body = models
    with pytest.raises(ShapeError, match="betas: expected shape .* got a scalar"):
        module(betas=torch.tensor(0.5))
    with pytest.raises(ShapeError, match="betas: expected shape .* got a scalar"):
        body(betas=0.5)
    with pytest.raises(TypeError, match="betas: sparse tensors are not accepted"):
        module(betas=torch.zeros(1, 10).to_sparse())
    with pytest.raises(TypeError, match=r"betas: a torch tensor that requires grad; .*detach\(\)"):
        body(betas=torch.zeros(1, 10, requires_grad=True))


def test_batch_zero_gives_empty_outputs(models):
    module, body = models
    out = body(body_pose=np.zeros((0, 69)), transl=np.zeros((1, 3)))
    assert out.vertices.shape == (0, 13380, 3) and out.joints.shape == (0, 45, 3)
    with torch.no_grad():
        t = module(body_pose=torch.zeros(0, 69))
    assert t.vertices.shape == (0, 13380, 3) and t.joints.shape == (0, 45, 3)
    assert body(betas=np.zeros((0, 10)), return_verts=False).joints.shape == (0, 45, 3)
