"""Sanity checks of the shipped open body model data (src/smplcore/data/open_model{,_male,_female}.npz).

Only numpy is needed; the files are loaded without pickle. Every check runs on the three genders.
"""

from pathlib import Path

import numpy as np
import pytest

from smplcore.family.names import EXTRA_JOINTS, SMPL_JOINTS

DATA = Path(__file__).parents[1] / "src/smplcore/data"
MODEL_FILES = {"neutral": "open_model.npz", "male": "open_model_male.npz", "female": "open_model_female.npz"}

SMPL_JOINT_NAMES = list(SMPL_JOINTS)
SMPL_PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]
EXTRA_JOINT_NAMES = list(EXTRA_JOINTS)
EXPECTED_KEYS = {
    "format",
    "model_type",
    "gender",
    "v_template",
    "faces",
    "shapedirs",
    "J_regressor",
    "weights",
    "parents",
    "joint_names",
    "extra_joint_names",
    "extra_joint_vertex_ids",
    "vt",
    "ft",
}
# Held-out max joint error of the regressor reported by tools/build_open_model.py
# (mm); the symmetry/containment checks below use a few mm of slack on top.
REPORTED_MAX_HELDOUT_ERROR_MM = 17.0


@pytest.fixture(scope="module", params=sorted(MODEL_FILES))
def model(request):
    with np.load(DATA / MODEL_FILES[request.param], allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["_gender"] = request.param
    arrays["_path"] = DATA / MODEL_FILES[request.param]
    return arrays


def _idx(name):
    return SMPL_JOINT_NAMES.index(name)


def _lr_pairs(names):
    return [(i, names.index("right_" + n[5:])) for i, n in enumerate(names) if n.startswith("left_")]


def test_keys_and_metadata(model):
    assert {k for k in model if not k.startswith("_")} == EXPECTED_KEYS
    assert "posedirs" not in model
    assert str(model["format"]) == "smplcore-model-1"
    assert str(model["model_type"]) == "open"
    assert str(model["gender"]) == model["_gender"]
    assert list(model["joint_names"]) == SMPL_JOINT_NAMES
    assert list(model["extra_joint_names"]) == EXTRA_JOINT_NAMES


def test_shapes_and_dtypes(model):
    V = model["v_template"].shape[0]
    K = model["shapedirs"].shape[2]
    assert model["v_template"].shape == (V, 3) and model["v_template"].dtype == np.float32
    assert model["faces"].ndim == 2 and model["faces"].shape[1] == 3 and model["faces"].dtype == np.int32
    assert model["shapedirs"].shape == (V, 3, K) and model["shapedirs"].dtype == np.float32
    assert 10 <= K <= 16
    assert model["J_regressor"].shape == (24, V) and model["J_regressor"].dtype == np.float32
    assert model["weights"].shape == (V, 24) and model["weights"].dtype == np.float32
    assert model["parents"].dtype == np.int32
    assert model["extra_joint_vertex_ids"].shape == (21,)
    assert model["extra_joint_vertex_ids"].dtype == np.int32
    for key in ("v_template", "shapedirs", "J_regressor", "weights"):
        assert np.all(np.isfinite(model[key])), key
    assert model["vt"].dtype == np.float32 and model["vt"].shape[1] == 2 and model["vt"].shape[0] > V
    assert model["ft"].shape == model["faces"].shape and model["ft"].dtype == np.int32
    assert model["ft"].min() == 0 and model["ft"].max() == model["vt"].shape[0] - 1
    assert model["_path"].stat().st_size <= 4 * 1024 * 1024


def test_parents(model):
    assert model["parents"].tolist() == SMPL_PARENTS


def test_weights(model):
    w = model["weights"]
    assert np.all(w >= 0)
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-5)


def test_faces(model):
    f = model["faces"]
    V = model["v_template"].shape[0]
    assert f.min() >= 0 and f.max() < V
    # every vertex is used
    assert np.unique(f).size == V
    # no repeated indices, no zero-area triangles
    assert np.all((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2]))
    tri = model["v_template"][f].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.min() > 1e-10
    # outward orientation: positive signed volume
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert vol > 0


def test_units_and_orientation(model):
    v = model["v_template"]
    height = v[:, 1].max() - v[:, 1].min()
    assert 1.5 < height < 1.9  # metres, Y up
    ids = dict(zip(EXTRA_JOINT_NAMES, model["extra_joint_vertex_ids"]))
    J = model["J_regressor"].astype(np.float64) @ v
    # root near the origin
    assert np.linalg.norm(J[0]) < 0.05
    # facing +Z: nose and toes in front of the head / ankles
    assert v[ids["nose"], 2] > J[_idx("head"), 2] + 0.05
    assert v[ids["left_big_toe"], 2] > J[_idx("left_ankle"), 2] + 0.1
    assert v[ids["left_heel"], 2] < J[_idx("left_ankle"), 2]
    # SMPL convention: the body's left is +X
    assert J[_idx("left_hip"), 0] > 0.03 and J[_idx("right_hip"), 0] < -0.03
    assert J[_idx("left_wrist"), 0] > 0.5
    for name in ("left_thumb", "left_index", "left_eye", "left_ear", "left_heel"):
        assert v[ids[name], 0] > 0
        assert v[ids[name.replace("left", "right")], 0] < 0
    # head on top, feet at the bottom
    assert J[_idx("head"), 1] > J[_idx("neck"), 1] > J[_idx("pelvis"), 1] > J[_idx("left_knee"), 1]


def test_tpose_joints_symmetric(model):
    J = model["J_regressor"].astype(np.float64) @ model["v_template"].astype(np.float64)
    for li, ri in _lr_pairs(SMPL_JOINT_NAMES):
        mirrored = J[ri] * [-1, 1, 1]
        assert np.linalg.norm(J[li] - mirrored) < 0.003, SMPL_JOINT_NAMES[li]
    for name in ("pelvis", "spine1", "spine2", "spine3", "neck", "head"):
        assert abs(J[_idx(name), 0]) < 0.003, name


def test_template_mesh_symmetric(model):
    ids = dict(zip(EXTRA_JOINT_NAMES, model["extra_joint_vertex_ids"]))
    v = model["v_template"].astype(np.float64)
    for name in EXTRA_JOINT_NAMES:
        if name.startswith("left_"):
            a, b = v[ids[name]], v[ids["right_" + name[5:]]]
            assert np.linalg.norm(a - b * [-1, 1, 1]) < 0.003, name


def test_arms_horizontal(model):
    J = model["J_regressor"].astype(np.float64) @ model["v_template"].astype(np.float64)
    for side in ("left", "right"):
        sh, el, wr, hd = (J[_idx(f"{side}_{k}")] for k in ("shoulder", "elbow", "wrist", "hand"))
        for p in (el, wr, hd):
            assert abs(p[1] - sh[1]) < 0.03
            assert abs(p[2] - sh[2]) < 0.03
        assert abs(sh[0]) < abs(el[0]) < abs(wr[0]) < abs(hd[0])
        assert abs(wr[0]) - abs(sh[0]) > 0.35


def test_beta0_height_monotonic(model):
    v = model["v_template"].astype(np.float64)
    d = model["shapedirs"][:, :, 0].astype(np.float64)
    heights = [np.ptp((v + b * d)[:, 1]) for b in np.linspace(-2, 2, 9)]
    assert np.all(np.diff(heights) > 0)
    assert heights[-1] - heights[0] > 0.2


def test_shapedirs_ordered(model):
    # beta_0 is the height axis (a rotation of the PCA space, which keeps beta ~ N(0, I)); the other
    # components follow ordered by the variance they carry (1 std each)
    s = model["shapedirs"].astype(np.float64)
    norms = np.linalg.norm(s.reshape(-1, s.shape[2]), axis=0)
    assert np.all(norms > 0)
    assert norms[0] > norms[1]
    assert np.all(np.diff(norms[1:]) <= 1e-6 * norms[1])
    # independent directions (the rotated basis is not orthogonal in vertex space, but it spans the PCA space)
    sv = np.linalg.svd(s.reshape(-1, s.shape[2]), compute_uv=False)
    assert sv.min() > 1e-3 * sv.max()


# Stature statistics of the shape space (see the build report, README "The open model"): adult
# populations sampled from NHANES stature and NCD-RisC BMI distributions.
EXPECTED_STATURE = {  # mean (m) at beta = 0, sd (cm) over beta ~ N(0, I): (lo, hi) ranges
    "neutral": ((1.66, 1.71), (8.5, 10.5)),
    "male": ((1.73, 1.78), (6.5, 8.5)),
    "female": ((1.60, 1.645), (6.0, 8.0)),
}


def test_stature_of_the_shape_space(model):
    v = model["v_template"].astype(np.float64)
    s = model["shapedirs"].astype(np.float64)
    (mean_lo, mean_hi), (sd_lo, sd_hi) = EXPECTED_STATURE[model["_gender"]]
    assert mean_lo < np.ptp(v[:, 1]) < mean_hi
    betas = np.random.default_rng(0).normal(size=(400, s.shape[2]))
    heights = np.ptp(v[None, :, 1] + betas @ s[:, 1, :].T, axis=1)
    assert sd_lo < heights.std() * 100 < sd_hi
    # beta_0 alone carries (almost) all of it: +-1 sd of beta_0 = +-1 sd of stature
    step = np.ptp(v[:, 1] + s[:, 1, 0]) - np.ptp(v[:, 1])
    assert abs(step * 100 - heights.std() * 100) < 0.6
    assert np.corrcoef(betas[:, 0], heights)[0, 1] > 0.98


def test_men_are_taller_than_women():
    heights = {}
    for gender, name in MODEL_FILES.items():
        with np.load(DATA / name, allow_pickle=False) as data:
            heights[gender] = np.ptp(data["v_template"][:, 1])
    assert heights["female"] + 0.1 < heights["male"]
    assert heights["female"] < heights["neutral"] < heights["male"]


def test_regressor(model):
    R = model["J_regressor"].astype(np.float64)
    assert np.all(R >= 0)
    np.testing.assert_allclose(R.sum(1), 1.0, atol=1e-5)
    nnz = (R > 0).sum(1)
    assert np.all(nnz >= 3) and np.all(nnz <= 400)


def test_regressed_joints_under_shape_changes(model):
    v0 = model["v_template"].astype(np.float64)
    s = model["shapedirs"].astype(np.float64)
    R = model["J_regressor"].astype(np.float64)
    tol = 0.003 + REPORTED_MAX_HELDOUT_ERROR_MM / 1000.0
    rng = np.random.default_rng(0)
    betas = [
        np.eye(s.shape[2])[0] * 2,
        -np.eye(s.shape[2])[0] * 2,
        np.eye(s.shape[2])[1] * 2,
        -np.eye(s.shape[2])[1] * 2,
        rng.normal(size=s.shape[2]) * 1.5,
    ]
    for beta in betas:
        v = v0 + s @ beta
        J = R @ v
        lo, hi = v.min(0), v.max(0)
        assert np.all(J > lo) and np.all(J < hi)
        for li, ri in _lr_pairs(SMPL_JOINT_NAMES):
            assert np.linalg.norm(J[li] - J[ri] * [-1, 1, 1]) < tol
        # joints stay near the skin-defined limb chain: children differ from parents
        bone = np.linalg.norm(J[1:] - J[np.asarray(SMPL_PARENTS[1:])], axis=1)
        assert np.all(bone > 0.01)


def test_extra_joint_ids(model):
    ids = model["extra_joint_vertex_ids"]
    V = model["v_template"].shape[0]
    assert ids.min() >= 0 and ids.max() < V
    assert len(set(ids.tolist())) == len(ids)
    v = model["v_template"]
    named = dict(zip(EXTRA_JOINT_NAMES, ids))
    # fingertips beyond the hand joints, toes in front of heels
    J = model["J_regressor"].astype(np.float64) @ v
    for f in ("index", "middle", "ring", "pinky"):
        assert v[named[f"left_{f}"], 0] > J[_idx("left_hand"), 0]
        assert v[named[f"right_{f}"], 0] < J[_idx("right_hand"), 0]
    assert v[named["left_big_toe"], 2] > v[named["left_heel"], 2] + 0.15
