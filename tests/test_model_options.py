"""Model options wired through both front ends: the open model's gender variants and ``uv_path=``."""

from __future__ import annotations

import numpy as np
import pytest

import fakes
import smplcore

torch = pytest.importorskip("torch")


def test_the_open_model_comes_in_three_genders_in_both_front_ends():
    heights = {}
    for gender in ("neutral", "male", "female"):
        body = smplcore.BodyModel(model_type="open", gender=gender)
        assert body.setup.data.source.endswith(
            {"neutral": "open_model.npz", "male": "open_model_male.npz", "female": "open_model_female.npz"}[gender]
        )
        module = smplcore.create(model_type="open", gender=gender)
        assert module.setup.data.source == body.setup.data.source and module.gender == gender
        v = body(return_verts=True).vertices[0]
        heights[gender] = v[:, 1].max() - v[:, 1].min()
    assert heights["male"] > heights["neutral"] > heights["female"]
    with pytest.raises(ValueError, match="gender: the open model comes as"):
        smplcore.BodyModel(model_type="open", gender="other")


def test_uv_path_attaches_smpl_s_separate_uv_map(fake_models, tmp_path):
    obj = fakes.write_smpl_uv_obj(tmp_path)
    body = smplcore.BodyModel(fake_models["smpl_neutral_pkl"], uv_path=obj)
    vt, ft = body.uv
    assert vt.shape == (7576, 2) and ft.shape == (13776, 3)
    module = smplcore.create(fake_models["smpl_neutral_pkl"], uv_path=obj)
    np.testing.assert_array_equal(module.setup.data.ft, ft)
    assert smplcore.BodyModel(fake_models["smpl_neutral_pkl"]).uv is None
