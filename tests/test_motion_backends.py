"""The motion pipeline's backends against the oracle, on vertices and joints of a translated motion."""

from __future__ import annotations

import numpy as np
import pytest

from oracle import oracle
from smplcore.motion import Evaluator, ModelCache, motion_from_arrays
from smplcore.motion.synthetic import random_arrays

pytest.importorskip("torch")


@pytest.mark.parametrize("backend", ["numpy", "torch"])
@pytest.mark.parametrize("skeleton_only", [False, True])
def test_motion_backends_equal_the_oracle_on_vertices_and_joints(fake_models, backend, skeleton_only):
    root = fake_models["smplh_neutral_pkl"].parent.parent
    motion = motion_from_arrays(random_arrays(7, model_type="smplh", gender="neutral", seed=2), "synthetic.npz")
    assert np.abs(motion.trans).max() > 0.5  # a translated motion: the bug this pins down shifted meshes by it
    loaded = ModelCache(root, backend=backend, vertices=True).get("smplh", "neutral")
    evaluator = Evaluator(chunk=3)  # several chunks
    params = evaluator.params(motion, loaded)
    expected_v, expected_j = oracle(
        loaded.model.setup.data, params, num_betas=loaded.model.num_betas, use_pca=False, flat_hand_mean=True
    )
    joints, verts = evaluator.run(motion, loaded, vertices=True)
    np.testing.assert_allclose(verts, expected_v, atol=2e-5, rtol=0)
    np.testing.assert_allclose(joints, expected_j, atol=2e-5, rtol=0)
    if skeleton_only:
        skeleton, _ = evaluator.run(motion, loaded, skeleton_only=True)
        np.testing.assert_allclose(skeleton, expected_j[:, : skeleton.shape[1]], atol=2e-5, rtol=0)
