"""UV maps in model files: SMPL-X's vt/ft, SMPL's separate UV .obj, smplcore's .npz, the open model."""

from __future__ import annotations

import numpy as np
import pytest

import fakes
from smplcore.errors import ModelFileError
from smplcore.io import load_model, save_npz
from smplcore.io.uv import attach_uv, load_uv_obj


def test_smplx_npz_and_pkl_carry_the_same_uv_map(fake_models):
    npz = load_model(fake_models["smplx_neutral_npz"])
    pkl = load_model(fake_models["smplx_neutral_pkl"])
    assert npz.has_uv and pkl.has_uv
    assert npz.vt.shape == (fakes.SMPLX_UVS, 2) and npz.ft.shape == (fakes.SMPLX_FACES, 3)
    assert npz.ft.dtype == np.int64
    np.testing.assert_array_equal(npz.ft, pkl.ft)
    np.testing.assert_allclose(npz.vt, pkl.vt)
    # seams: more UVs than vertices, some vertices with two UVs
    uv_per_vertex = np.zeros(npz.num_vertices, dtype=int)
    pairs = np.unique(np.stack([npz.faces.ravel(), npz.ft.ravel()], axis=1), axis=0)
    np.add.at(uv_per_vertex, pairs[:, 0], 1)
    assert npz.vt.shape[0] > npz.num_vertices and uv_per_vertex.max() == 2 and uv_per_vertex.min() == 1


def test_smpl_file_has_no_uv_and_the_uv_obj_attaches(fake_models, tmp_path):
    smpl = load_model(fake_models["smpl_neutral_pkl"])
    assert not smpl.has_uv and smpl.vt is None
    obj = fakes.write_smpl_uv_obj(tmp_path)
    vt, ft, faces = load_uv_obj(obj)
    assert vt.shape == (fakes.SMPL_UVS, 2) and ft.shape == (fakes.SMPL_FACES, 3)
    np.testing.assert_array_equal(faces, smpl.faces)
    with_uv = attach_uv(smpl, obj)
    np.testing.assert_array_equal(with_uv.ft, ft)
    np.testing.assert_allclose(with_uv.vt, vt)
    # the same map with its faces permuted and their corners rotated is matched back to the model's faces
    shuffled = attach_uv(smpl, fakes.write_smpl_uv_obj(tmp_path, name="shuffled.obj", shuffle_faces=True))
    np.testing.assert_array_equal(shuffled.ft, with_uv.ft)
    # and survives smplcore's .npz
    again = load_model(save_npz(with_uv, tmp_path / "smpl_uv.npz"))
    np.testing.assert_array_equal(again.ft, with_uv.ft)
    np.testing.assert_allclose(again.vt, with_uv.vt)


def test_uv_obj_of_another_mesh_is_refused(fake_models, tmp_path):
    smplx = load_model(fake_models["smplx_neutral_npz"])
    with pytest.raises(ModelFileError, match="triangles.*not the same mesh"):
        attach_uv(smplx, fakes.write_smpl_uv_obj(tmp_path))
    bad = tmp_path / "no_uv.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ModelFileError, match="no texture index"):
        load_uv_obj(bad)
    with pytest.raises(ModelFileError, match="no such UV file"):
        load_uv_obj(tmp_path / "missing.obj")


def test_bad_uv_arrays_name_the_key(fake_models, tmp_path):
    smplx = load_model(fake_models["smplx_neutral_npz"])
    path = save_npz(smplx, tmp_path / "m.npz")
    with np.load(path) as data:
        arrays = dict(data)
    arrays["ft"] = arrays["ft"][:-1]
    np.savez(tmp_path / "short_ft.npz", **arrays)
    with pytest.raises(ModelFileError, match="'ft'.*one row per mesh face"):
        load_model(tmp_path / "short_ft.npz")
    arrays = {k: v for k, v in np.load(path).items() if k != "vt"}
    np.savez(tmp_path / "no_vt.npz", **arrays)
    with pytest.raises(ModelFileError, match="needs both 'vt' and 'ft'"):
        load_model(tmp_path / "no_vt.npz")


def test_open_model_has_makehuman_uvs():
    import smplcore

    data = smplcore.BodyModel(model_type="open").setup.data
    assert data.has_uv
    assert data.vt.shape[0] > data.num_vertices  # seams
    assert data.ft.shape == data.faces.shape
    assert data.vt.min() >= 0.0 and data.vt.max() <= 1.0
    # every UV triangle has positive area (no collapsed faces in the map)
    t = data.vt[data.ft]
    a, b = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert area.min() > 0
