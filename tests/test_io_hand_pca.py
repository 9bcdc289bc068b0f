"""Empty hand-PCA arrays (as some AMASS SMPL+H downloads carry) mean "no hand PCA", as in smplx."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import smplcore
from smplcore.errors import ModelFileError
from smplcore.io import load_model


class Struct:
    def __init__(self, **kwargs):
        self.__dict__.update(kwargs)


def _with_empty_hand_pca(src: Path, dst: Path) -> Path:
    with np.load(src, allow_pickle=True) as data:
        arrays = {k: data[k] for k in data.files}
    for key in ("hands_componentsl", "hands_componentsr", "hands_meanl", "hands_meanr"):
        arrays[key] = np.zeros((0,))
    np.savez(dst, **arrays)
    return dst


def test_a_file_with_empty_hand_pca_loads_without_hand_pca(fake_models, tmp_path):
    path = _with_empty_hand_pca(fake_models["official_smplh_amass_neutral_npz"], tmp_path / "model.npz")
    data = load_model(path, model_type="smplh")
    assert data.model_type == "smplh" and data.num_joints == 52
    assert data.hands_components_left is None and data.hands_components_right is None
    assert data.hands_mean_left is None and data.hands_mean_right is None


def test_create_from_a_data_struct_with_empty_hand_pca(fake_models, tmp_path):
    import torch

    path = _with_empty_hand_pca(fake_models["official_smplh_amass_neutral_npz"], tmp_path / "model.npz")
    with np.load(path, allow_pickle=True) as data:
        struct = Struct(**{k: data[k] for k in data.files})
    model = smplcore.create(model_type="smplh", data_struct=struct, use_pca=False, num_betas=16)
    out = model(left_hand_pose=torch.zeros(1, 45), right_hand_pose=torch.zeros(1, 45))
    reference = smplcore.create(
        str(fake_models["official_smplh_amass_neutral_npz"]), model_type="smplh", use_pca=False, num_betas=16
    )()
    torch.testing.assert_close(out.vertices, reference.vertices)
    with pytest.raises(ModelFileError, match="use_pca=True needs the left hand's PCA components"):
        smplcore.create(model_type="smplh", data_struct=struct, use_pca=True)
