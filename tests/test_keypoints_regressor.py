"""Extra joint regressors: loading dense / sparse / pickled files safely, applying them, the open model's own."""

from __future__ import annotations

import os
import pickle

import numpy as np
import pytest
import scipy.sparse as sp

import smplcore
from smplcore import keypoints as kp
from smplcore.errors import ModelFileError, ShapeError

V = 50


def _matrix(k=17, seed=0):
    rng = np.random.default_rng(seed)
    m = np.zeros((k, V))
    for row in m:
        cols = rng.choice(V, 4, replace=False)
        row[cols] = rng.dirichlet(np.ones(4))
    return m


def test_dense_npy(tmp_path):
    m = _matrix()
    np.save(tmp_path / "J_regressor_h36m.npy", m)
    reg = kp.Regressor.load(tmp_path / "J_regressor_h36m.npy", convention="h36m17", num_vertices=V)
    assert reg.names == kp.names("h36m17") and reg.convention == "h36m17"
    np.testing.assert_array_equal(reg.matrix, m)
    np.testing.assert_array_equal(reg.vertex_ids, np.flatnonzero(m.any(axis=0)))
    verts = np.random.default_rng(1).normal(size=(2, V, 3))
    np.testing.assert_allclose(reg.apply(verts), m @ verts, rtol=1e-12)
    np.testing.assert_allclose(reg.apply_subset(verts[:, reg.vertex_ids]), m @ verts, rtol=1e-12)
    assert reg.qualified_names()[0] == "h36m17:pelvis"


def test_sparse_npz_and_names_in_the_file(tmp_path):
    m = _matrix(9)
    sp.save_npz(tmp_path / "extra.npz", sp.csr_matrix(m))
    reg = kp.Regressor.load(tmp_path / "extra.npz")
    assert sp.issparse(reg.matrix) and reg.names == tuple(f"extra_{k}" for k in range(9))
    np.testing.assert_allclose(reg.matrix.toarray(), m)
    np.savez(tmp_path / "named.npz", J_regressor=m[:3], names=np.array(["a", "b", "c"]))
    assert kp.Regressor.load(tmp_path / "named.npz").names == ("a", "b", "c")


def test_pickled_dense_and_sparse(tmp_path):
    m = _matrix()
    with open(tmp_path / "dict.pkl", "wb") as fh:
        pickle.dump({"J_regressor_extra": sp.csc_matrix(m)}, fh, protocol=2)
    with open(tmp_path / "plain.pkl", "wb") as fh:
        pickle.dump(m, fh)
    np.save(tmp_path / "object.npy", np.array(sp.csr_matrix(m), dtype=object), allow_pickle=True)
    for name in ("dict.pkl", "plain.pkl", "object.npy"):
        reg = kp.Regressor.load(tmp_path / name, convention="coco17")
        dense = reg.matrix.toarray() if sp.issparse(reg.matrix) else reg.matrix
        np.testing.assert_allclose(dense, m, err_msg=name)


class _Evil:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def test_malicious_pickle_is_refused_without_running_it(tmp_path):
    marker = tmp_path / "pwned"
    path = tmp_path / "J_regressor_extra.pkl"
    with open(path, "wb") as fh:
        pickle.dump({"J_regressor": _Evil(marker)}, fh)
    with pytest.raises(ModelFileError, match="refused to load.*nothing in the file was run") as info:
        kp.Regressor.load(path)
    assert str(path) in str(info.value)
    np.save(tmp_path / "evil.npy", np.array(_Evil(marker), dtype=object), allow_pickle=True)
    with pytest.raises(ModelFileError, match="refused to load"):
        kp.Regressor.load(tmp_path / "evil.npy")
    assert not marker.exists()


def test_bad_files_name_the_file_and_the_problem(tmp_path):
    np.save(tmp_path / "r.npy", _matrix())
    with pytest.raises(ModelFileError, match=r"r\.npy: the regressor has 50 columns but the model has 6890 vertices"):
        kp.Regressor.load(tmp_path / "r.npy", num_vertices=6890)
    with pytest.raises(ModelFileError, match="17 rows but convention 'openpose25' has 25 points"):
        kp.Regressor.load(tmp_path / "r.npy", convention="openpose25")
    with pytest.raises(ModelFileError, match="no such file"):
        kp.Regressor.load(tmp_path / "missing.npy")
    np.save(tmp_path / "v.npy", np.zeros(5))
    with pytest.raises(ModelFileError, match=r"expected a \(K, V\) matrix, found shape \(5,\)"):
        kp.Regressor.load(tmp_path / "v.npy")
    (tmp_path / "t.npy").write_bytes(np.lib.format.magic(1, 0) + b"\x10\x00{'descr'")
    with pytest.raises(ModelFileError, match="truncated or corrupt"):
        kp.Regressor.load(tmp_path / "t.npy")
    np.savez(tmp_path / "two.npz", a=np.zeros((2, 3)), b=np.zeros((2, 3)))
    with pytest.raises(ModelFileError, match="pass key= to name it"):
        kp.Regressor.load(tmp_path / "two.npz")
    assert kp.Regressor.load(tmp_path / "two.npz", key="b").matrix.shape == (2, 3)
    reg = kp.Regressor.load(tmp_path / "r.npy")
    with pytest.raises(ShapeError, match=r"vertices: expected shape \(\.\.\., 50, D\)"):
        reg.apply(np.zeros((1, 49, 3)))


def test_apply_with_torch_matches_numpy():
    torch = pytest.importorskip("torch")
    reg = kp.Regressor(sp.csr_matrix(_matrix()), kp.names("coco17"), "coco17")
    verts = np.random.default_rng(4).normal(size=(3, V, 3))
    t = torch.tensor(verts, dtype=torch.float32, requires_grad=True)
    out = reg.apply(t)
    assert out.shape == (3, 17, 3) and out.dtype == torch.float32
    np.testing.assert_allclose(out.detach().numpy(), reg.apply(verts), rtol=1e-5, atol=1e-6)
    out.sum().backward()
    assert t.grad.shape == t.shape


@pytest.fixture(scope="module")
def open_tpose():
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    out = model()
    return model, out.vertices[0], out.joints[0]


def test_open_model_coco17_lands_on_the_right_body_parts(open_tpose):
    model, verts, joints = open_tpose
    reg = kp.open_model_regressor("coco17")
    reg.check(verts.shape[0])
    coco = dict(zip(kp.names("coco17"), reg.apply(verts), strict=True))
    head = joints[model.joint_names.index("head")]
    floor = verts[:, 1].min()
    assert coco["nose"][2] > head[2] + 0.05  # in front of the head (the body faces +z)
    assert coco["nose"][1] > coco["left_shoulder"][1] + 0.1
    for side in ("left", "right"):
        assert 0.0 < coco[f"{side}_ankle"][1] - floor < 0.12  # near the floor
        assert coco[f"{side}_ankle"][1] < coco[f"{side}_knee"][1] < coco[f"{side}_hip"][1]
        assert coco[f"{side}_eye"][1] > coco["nose"][1] - 0.02
    for name, point in coco.items():
        if name.startswith("left_"):
            assert point[0] > 0.02, name  # left is +x
            right = coco["right_" + name[5:]]
            np.testing.assert_allclose(right, point * [-1, 1, 1], atol=1e-3)  # the open model is symmetric


def test_open_model_h36m_and_body25(open_tpose):
    model, verts, joints = open_tpose
    h36m = dict(zip(kp.names("h36m17"), kp.open_model_regressor("h36m17").apply(verts), strict=True))
    assert abs(h36m["head_top"][1] - verts[:, 1].max()) < 1e-6
    np.testing.assert_allclose(h36m["pelvis"], joints[0], atol=1e-6)
    assert h36m["pelvis"][1] < h36m["spine"][1] < h36m["thorax"][1] < h36m["neck_nose"][1] < h36m["head_top"][1]
    body25 = kp.open_model_regressor("openpose25").apply(verts)
    names = kp.names("openpose25")
    np.testing.assert_allclose(body25[1], 0.5 * (body25[2] + body25[5]), atol=1e-6)  # neck = mid-shoulders
    for name in ("left_big_toe", "left_heel", "right_small_toe"):
        np.testing.assert_allclose(body25[names.index(name)], joints[model.joint_names.index(name)], atol=1e-6)
    assert body25[names.index("left_big_toe")][2] > body25[names.index("left_heel")][2] + 0.15
    with pytest.raises(ValueError, match="the open model ships regressors for"):
        kp.open_model_regressor("mpii16")


def test_open_model_regressor_follows_the_posed_mesh():
    torch = pytest.importorskip("torch")
    model = smplcore.create(model_type="open")
    pose = torch.zeros(1, 69)
    pose[0, 3 * 15 + 2] = -1.2  # lower the left arm (body_pose starts at joint 1; the left shoulder is 16)
    with torch.no_grad():
        out = model(body_pose=pose)
    coco = kp.open_model_regressor("coco17").apply(out.vertices)[0]
    smpl = kp.convert(out.joints, model, "coco17")[0][0]
    wrist = kp.names("coco17").index("left_wrist")
    assert float(coco[wrist, 1]) < 0.2  # the wrist went down with the arm
    assert float((coco[wrist] - smpl[wrist]).norm()) < 0.05


class _ModelWithRegressors:
    """Stands for a model whose outputs have regressor joints appended under qualified names."""

    def __init__(self, joint_names):
        self.joint_names = joint_names


def test_load_regressors_stacks_them_under_qualified_names(tmp_path, open_tpose):
    model, verts, joints = open_tpose
    np.save(tmp_path / "extra.npy", np.eye(verts.shape[0])[[10, 20, 30]])
    both = kp.load_regressors({"h36m17": "open", "extra": tmp_path / "extra.npy"}, num_vertices=verts.shape[0])
    assert both.names[:2] == ("h36m17:pelvis", "h36m17:left_hip") and both.names[-3:] == (
        "extra_0",
        "extra_1",
        "extra_2",
    )
    assert both.matrix.shape == (20, verts.shape[0])
    h36m = kp.open_model_regressor("h36m17")
    assert set(h36m.vertex_ids) | {10, 20, 30} == set(both.vertex_ids)
    appended = both.apply_subset(verts[both.vertex_ids])
    np.testing.assert_allclose(appended, both.apply(verts), atol=1e-12)
    np.testing.assert_allclose(appended[17:], verts[[10, 20, 30]], atol=1e-12)
    # a model's outputs with the regressor joints appended: convert takes H36M's points from them, exactly
    outputs = np.concatenate([joints, appended])
    fake = _ModelWithRegressors(model.joint_names + list(both.names))
    out, mask = kp.convert(outputs, fake, "h36m17", exact_only=True)
    assert mask.all()
    np.testing.assert_allclose(out, h36m.apply(verts), atol=1e-9)  # float64, summation order differs
    np.testing.assert_array_equal(kp.convert(outputs, fake, "smpl24")[0], joints[:24])  # its own joints stay first
    with pytest.raises(ModelFileError, match="the model has 6890 vertices"):
        kp.load_regressors({"coco17": "open"}, num_vertices=6890)
    with pytest.raises(ValueError, match="'open' needs a convention name"):
        kp.load_regressors({"mine": "open"})


def test_flame_model_outputs_are_the_flame_convention(fake_models):
    model = smplcore.BodyModel(fake_models["root"], model_type="flame", dtype=np.float64, use_face_contour=True)
    joints = model().joints
    out, mask = kp.convert(joints, model, "flame")
    assert mask.all()
    np.testing.assert_array_equal(out, joints)
    smplx_face, mask = kp.convert(joints, model, "smplx144", exact_only=True)
    assert mask.sum() == 71  # the jaw, the eyeballs (SMPL-X's *_smplhf joints) and the 68 face points
