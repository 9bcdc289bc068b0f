"""The exporters' skinning (the rig an exported glTF/BVH carries: rest mesh, weights, per-frame joint
transforms) against the oracle, on vertices and joints, for a model without pose correctives."""

from __future__ import annotations

import numpy as np

import smplcore
from oracle import oracle
from smplcore.export.animation import lbs, prepare_animation
from smplcore.motion import motion_from_arrays
from smplcore.motion.synthetic import random_arrays


def test_exported_rig_reproduces_the_oracle_on_vertices_and_joints():
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    motion = motion_from_arrays(random_arrays(5, model_type="smplh", gender="neutral", seed=3), "walk.npz")
    anim = prepare_animation(model, motion)
    params = motion.model_params("open")
    params["betas"] = np.broadcast_to(anim.betas, (5, anim.betas.shape[0]))
    expected_v, expected_j = oracle(model.setup.data, params, num_betas=model.num_betas)
    verts = lbs(anim.rest_vertices, anim.skinning_matrices(), anim.weights)
    np.testing.assert_allclose(verts, expected_v, atol=1e-6, rtol=0)
    np.testing.assert_allclose(anim.joints(), expected_j[:, :24], atol=1e-6, rtol=0)
