"""The open model through the public API: loads with no files, drives with SMPL poses, bends where it should."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.family.names import SMPL_JOINTS


@pytest.fixture(scope="module")
def model():
    return smplcore.BodyModel(model_type="open")


def _body_pose(**rotations):
    pose = np.zeros((1, 23, 3))
    for name, rotvec in rotations.items():
        pose[0, SMPL_JOINTS.index(name) - 1] = rotvec
    return pose.reshape(1, -1)


def test_open_model_loads_with_no_files_in_both_front_ends(model):
    torch = pytest.importorskip("torch")
    module = smplcore.create(model_type="open")
    assert type(module).__name__ == "OpenModel" and module.name() == "OPEN"
    out = module(body_pose=torch.zeros(2, 69), betas=torch.zeros(2, 10), transl=torch.zeros(2, 3))
    ref = model(body_pose=np.zeros((2, 69)), betas=np.zeros((2, 10)))
    assert out.joints.shape == (2, 45, 3) and ref.joints.shape == (2, 45, 3)
    np.testing.assert_allclose(out.vertices.detach().numpy(), ref.vertices, atol=1e-5)
    assert model.joint_names[:24] == list(SMPL_JOINTS) and model.joint_names[24] == "nose"
    assert not model.has_pose_correctives


def test_bending_the_left_elbow_moves_the_left_forearm_only(model):
    rest = model().vertices[0]
    bent = model(body_pose=_body_pose(left_elbow=(0.0, 1.2, 0.0))).vertices[0]
    moved = np.linalg.norm(bent - rest, axis=1)
    owner = model.skinning_weights.argmax(axis=1)
    left_forearm = np.isin(owner, [SMPL_JOINTS.index(n) for n in ("left_wrist", "left_hand")])
    right_arm = np.isin(
        owner,
        [SMPL_JOINTS.index(n) for n in ("right_collar", "right_shoulder", "right_elbow", "right_wrist", "right_hand")],
    )
    assert moved[left_forearm].min() > 0.02
    assert moved[right_arm].max() < 1e-6


def test_smpl_body_poses_drive_it_standing_upright(model):
    rng = np.random.default_rng(0)
    # Standing poses: small random joint rotations everywhere, legs nearly straight.
    pose = rng.normal(0, 0.15, (16, 69))
    out = model(body_pose=pose, betas=rng.normal(0, 1, (16, 10)))
    head, feet = SMPL_JOINTS.index("head"), [SMPL_JOINTS.index("left_foot"), SMPL_JOINTS.index("right_foot")]
    assert np.isfinite(out.vertices).all()
    assert (out.joints[:, feet, 1].max(axis=1) < out.joints[:, head, 1] - 0.5).all()


def test_beta_zero_is_height(model):
    heights = []
    for b0 in (-1.0, 0.0, 1.0):
        betas = np.zeros((1, 10))
        betas[0, 0] = b0
        v = model(betas=betas).vertices[0]
        heights.append(v[:, 1].max() - v[:, 1].min())
    assert heights[0] < heights[1] < heights[2]


def test_open_model_files_per_gender():
    """Neutral, male and female files (as SMPL ships three): same mesh, skeleton, skinning and UV map."""
    from smplcore.io import load_model
    from smplcore.io.open_model import open_model_path

    models = {g: load_model(open_model_path(g)) for g in ("neutral", "male", "female")}
    for gender, data in models.items():
        assert data.model_type == "open" and data.gender == gender and data.has_uv
        np.testing.assert_array_equal(data.faces, models["neutral"].faces)
        np.testing.assert_array_equal(data.ft, models["neutral"].ft)
        np.testing.assert_array_equal(data.vt, models["neutral"].vt)
        np.testing.assert_array_equal(data.weights, models["neutral"].weights)
        np.testing.assert_array_equal(data.parents, models["neutral"].parents)
    assert open_model_path("F") == open_model_path("female") and open_model_path(None) == open_model_path()
    assert open_model_path().name == "open_model.npz"
    with pytest.raises(ValueError, match=r"gender: the open model comes as \['female', 'male', 'neutral'\]"):
        open_model_path("kid")
