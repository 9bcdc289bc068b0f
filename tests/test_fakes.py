"""The fake official files of ``tests/fakes/`` are valid: smplx 0.1.28 loads them and produces
sensible meshes, and their structure (keys, shapes, dtypes, pickle format) is the official one."""

from __future__ import annotations

import pickle
import pickletools
import warnings

import numpy as np
import pytest
import scipy.sparse as sp

import fakes

torch = pytest.importorskip("torch")
smplx = pytest.importorskip("smplx")
pytest.importorskip("chumpy")

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

LEGACY_GLOBALS = {
    "__builtin__ set",
    "chumpy.ch Ch",
    "numpy dtype",
    "numpy ndarray",
    "numpy.core.multiarray _reconstruct",
    "numpy.core.multiarray scalar",
    "scipy.sparse.csc csc_matrix",
}


def _load_pkl(path):
    with open(path, "rb") as fh:
        return pickle.load(fh, encoding="latin1")


def _globals(path):
    """The ``module name`` globals a pickle refers to (any protocol)."""
    out = set()

    class Recorder(pickle.Unpickler):
        def find_class(self, module, name):
            out.add(f"{module} {name}")
            return super().find_class(module, name)

    with open(path, "rb") as fh:
        Recorder(fh, encoding="latin1").load()
    return out


def _protocol(path):
    with open(path, "rb") as fh:
        op, arg, _ = next(pickletools.genops(fh))
    assert op.name == "PROTO"
    return arg


def _forward(model, seed=0, **extra):
    g = torch.Generator().manual_seed(seed)
    kw = {}
    for name in (
        "global_orient",
        "body_pose",
        "left_hand_pose",
        "right_hand_pose",
        "hand_pose",
        "jaw_pose",
        "neck_pose",
    ):
        p = getattr(model, name, None)
        if p is not None:
            kw[name] = 0.3 * torch.randn(p.shape, generator=g)
    kw["betas"] = torch.randn(model.betas.shape, generator=g)
    if getattr(model, "expression", None) is not None:
        kw["expression"] = torch.randn(model.expression.shape, generator=g)
    kw.update(extra)
    with torch.no_grad():
        out = model(**kw)
    return out


def _check_plausible(out, max_extent=3.0, min_height=None):
    v = out.vertices[0].numpy()
    j = out.joints[0].numpy()
    assert np.isfinite(v).all() and np.isfinite(j).all()
    assert np.abs(v).max() < max_extent
    ext = v.max(0) - v.min(0)
    assert ext.max() < max_extent
    if min_height is not None:
        assert ext[1] > min_height
    return v, j


# ------------------------------------------------------------------ the tree


def test_write_all_layout(fake_models):
    root = fake_models["root"]
    for key, path in fake_models.items():
        if key != "root":
            assert path.is_file(), key
            assert root in path.parents
    assert fake_models["smpl_neutral_pkl"] == root / "smpl" / "SMPL_NEUTRAL.pkl"
    assert fake_models["smplx_neutral_npz"] == root / "smplx" / "SMPLX_NEUTRAL.npz"
    assert fake_models["mano_left_pkl"] == root / "mano" / "MANO_LEFT.pkl"
    assert fake_models["flame_neutral_pkl"] == root / "flame" / "FLAME_NEUTRAL.pkl"


# ------------------------------------------------------------------ SMPL


@pytest.mark.parametrize("gender,nb", [("neutral", 300), ("male", 10), ("female", 10)])
def test_smpl_loads_in_smplx(fake_models, gender, nb):
    m = smplx.create(str(fake_models["root"]), model_type="smpl", gender=gender, num_betas=300)
    assert m.num_betas == nb
    assert m.get_num_verts() == 6890 and m.get_num_faces() == 13776
    _, j = _check_plausible(_forward(m), min_height=1.2)
    assert j.shape == (45, 3)  # 24 joints + 21 vertex-selected extra joints


def test_smplx_ignores_ext_for_smpl(fake_models):
    root = str(fake_models["root"])
    a = _forward(smplx.create(root, model_type="smpl", ext="npz", num_betas=10)).vertices
    b = _forward(smplx.create(root, model_type="smpl", num_betas=10)).vertices
    assert torch.equal(a, b)


def test_smpl_pickle_is_legacy_format(fake_models):
    path = fake_models["smpl_female_pkl"]
    assert _globals(path) <= LEGACY_GLOBALS
    with pytest.raises(UnicodeDecodeError), open(path, "rb") as fh:  # real files need latin1
        pickle.load(fh)
    d = _load_pkl(path)
    assert set(d) == {
        "J_regressor_prior",
        "f",
        "J_regressor",
        "kintree_table",
        "J",
        "weights_prior",
        "weights",
        "vert_sym_idxs",
        "posedirs",
        "pose_training_info",
        "bs_style",
        "v_template",
        "shapedirs",
        "bs_type",
    }
    import chumpy

    assert type(d["shapedirs"]) is chumpy.Ch and d["shapedirs"].shape == (6890, 3, 10)
    assert isinstance(d["J_regressor"], sp.csc_matrix) and d["J_regressor"].shape == (24, 6890)
    assert isinstance(d["J_regressor_prior"], sp.csc_matrix)
    assert d["f"].dtype == np.uint32 and d["f"].shape == (13776, 3)
    assert d["kintree_table"].dtype == np.int64 and d["kintree_table"].shape == (2, 24)
    assert d["kintree_table"][0, 0] == 4294967295
    assert (d["kintree_table"][1] == np.arange(24)).all()
    for k in ("v_template", "J", "weights", "weights_prior", "posedirs"):
        assert d[k].dtype == np.float64, k
    assert d["posedirs"].shape == (6890, 3, 207)
    assert d["bs_style"] == "lbs" and d["bs_type"] == "lrotmin"
    assert isinstance(d["pose_training_info"], dict)
    np.testing.assert_allclose(d["J"], d["J_regressor"] @ d["v_template"])
    sym = d["vert_sym_idxs"]
    assert (sym[sym] == np.arange(6890)).all()
    np.testing.assert_allclose(d["v_template"][sym] * [-1, 1, 1], d["v_template"], atol=1e-12)


def test_smpl_v11_has_300_betas_and_npz_matches(fake_models):
    d = _load_pkl(fake_models["smpl_neutral_pkl"])
    assert np.asarray(d["shapedirs"]).shape == (6890, 3, 300)
    z = np.load(fake_models["smpl_neutral_npz"])  # no allow_pickle needed
    for k in ("v_template", "f", "weights", "posedirs", "kintree_table", "J", "vert_sym_idxs"):
        np.testing.assert_array_equal(z[k], d[k])
    np.testing.assert_array_equal(z["shapedirs"], np.asarray(d["shapedirs"]))
    np.testing.assert_array_equal(z["J_regressor"], d["J_regressor"].toarray())
    assert str(z["bs_style"]) == "lbs"


def test_official_names(fake_models):
    off = fake_models["root"] / "official"
    assert (off / "smpl" / "basicModel_f_lbs_10_207_0_v1.0.0.pkl").is_file()
    assert _load_pkl(off / "smpl" / "basicModel_f_lbs_10_207_0_v1.0.0.pkl")["f"].shape == (13776, 3)
    m = smplx.SMPL(str(off / "smpl" / "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl"), num_betas=300)
    assert m.num_betas == 300
    assert (off / "flame" / "generic_model.pkl").is_file()


def test_smpl_kid(fake_models):
    m = smplx.create(
        str(fake_models["root"]),
        model_type="smpl",
        age="kid",
        num_betas=10,
        kid_template_path=str(fake_models["smpl_kid_template"]),
    )
    assert m.num_betas == 11
    _check_plausible(_forward(m), min_height=0.6)


# ------------------------------------------------------------------ SMPL+H


@pytest.mark.parametrize("use_pca", [True, False])
def test_smplh_pkl_loads(fake_models, use_pca):
    m = smplx.create(str(fake_models["root"]), model_type="smplh", use_pca=use_pca, num_pca_comps=12)
    assert m.num_betas == 10 and m.parents.shape == (52,)
    _check_plausible(_forward(m), min_height=1.2)


def test_smplh_amass_npz_with_hands_loads(fake_models):
    m = smplx.create(str(fake_models["root"]), model_type="smplh", gender="female", ext="npz", num_betas=16)
    assert m.num_betas == 10  # smplx caps any basis narrower than 300 at 10
    assert np.load(fake_models["smplh_female_npz"])["shapedirs"].shape == (6890, 3, 16)
    _check_plausible(_forward(m), min_height=1.2)


def test_raw_smplh_files_lack_hand_pca_like_the_real_ones(fake_models):
    raw_pkl = fake_models["official_smplh_male_pkl"]
    assert raw_pkl.name == "SMPLH_male.pkl"
    d = _load_pkl(raw_pkl)
    assert not any(k.startswith("hands_") for k in d)
    assert _globals(raw_pkl) <= LEGACY_GLOBALS
    with pytest.raises(AttributeError, match="hands_componentsl"):
        smplx.SMPLH(str(raw_pkl), ext="pkl")
    amass = fake_models["official_smplh_amass_neutral_npz"]
    assert amass.parts[-2:] == ("neutral", "model.npz")
    z = np.load(amass)
    assert z["shapedirs"].shape == (6890, 3, 16) and z["posedirs"].shape == (6890, 3, 459)
    assert not any(k.startswith("hands_") for k in z.files)
    with pytest.raises(AttributeError, match="hands_componentsl"):
        smplx.SMPLH(str(amass), ext="npz")


def test_smplh_hand_pca_matches_mano(fake_models):
    h = _load_pkl(fake_models["smplh_neutral_pkl"])
    r = _load_pkl(fake_models["mano_right_pkl"])
    left = _load_pkl(fake_models["mano_left_pkl"])
    np.testing.assert_array_equal(h["hands_componentsr"], r["hands_components"])
    np.testing.assert_array_equal(h["hands_componentsl"], left["hands_components"])
    np.testing.assert_array_equal(h["hands_meanl"], left["hands_mean"])
    assert h["hands_coeffsl"].shape == (1554, 45)


# ------------------------------------------------------------------ SMPL-X


def test_smplx_npz_full(fake_models):
    z = np.load(fake_models["smplx_neutral_npz"], allow_pickle=True)
    assert z["shapedirs"].shape == (10475, 3, 400)
    assert z["posedirs"].shape == (10475, 3, 486)
    assert z["J_regressor"].shape == (55, 10475)
    assert z["vt"].shape == (11313, 2) and z["ft"].shape == (20908, 3)
    assert z["ft"].max() < 11313
    assert isinstance(z["joint2num"][()], dict) and len(z["joint2num"][()]) == 55
    assert "allow_pickle" in z.files and "J" not in z.files
    m = smplx.create(
        str(fake_models["root"]),
        model_type="smplx",
        num_betas=300,
        num_expression_coeffs=100,
        use_face_contour=True,
        use_pca=False,
    )
    assert m.num_betas == 300 and m.num_expression_coeffs == 100
    _, j = _check_plausible(_forward(m), min_height=1.2)
    assert j.shape == (55 + 21 + 51 + 17, 3)


def test_smplx_pkl_equals_npz(fake_models):
    root = str(fake_models["root"])
    kw = {"model_type": "smplx", "num_betas": 20, "num_expression_coeffs": 20, "use_face_contour": True}
    a = _forward(smplx.create(root, ext="npz", **kw))
    b = _forward(smplx.create(root, ext="pkl", **kw))
    assert torch.equal(a.vertices, b.vertices) and torch.equal(a.joints, b.joints)
    assert _globals(fake_models["smplx_neutral_pkl"]) <= LEGACY_GLOBALS


def test_smplx_layout_10(fake_models):
    m = smplx.create(
        str(fake_models["root"]),
        model_type="smplx",
        gender="male",
        num_betas=300,
        num_expression_coeffs=100,
        use_pca=True,
        num_pca_comps=6,
    )
    assert m.num_betas == 10 and m.num_expression_coeffs == 10
    _check_plausible(_forward(m), min_height=1.2)


def test_smplx_kid(fake_models):
    m = smplx.create(
        str(fake_models["root"]),
        model_type="smplx",
        age="kid",
        num_betas=10,
        kid_template_path=str(fake_models["smplx_kid_template"]),
    )
    assert m.num_betas == 11
    _check_plausible(_forward(m), min_height=0.6)


def test_smplx_contour_follows_head_turn(fake_models):
    m = smplx.create(str(fake_models["root"]), model_type="smplx", use_face_contour=True)
    outs = []
    for yaw in (-0.6, 0.0, 0.6):
        pose = torch.zeros(1, 63)
        pose[0, 11 * 3 + 1] = yaw  # neck (joint 12) about y
        with torch.no_grad():
            outs.append(m(body_pose=pose).joints[0, -17:])
    assert not torch.equal(outs[0], outs[2])
    assert all(torch.isfinite(o).all() for o in outs)


def test_smplx_expressions_only_move_the_face(fake_models):
    m = smplx.create(str(fake_models["root"]), model_type="smplx", num_expression_coeffs=100)
    moving = m.expr_dirs.abs().sum(dim=(1, 2)) > 0
    neck_y = m.J_regressor[12] @ m.v_template[:, 1]
    assert moving.any()
    assert (m.v_template[moving, 1] > neck_y - 0.05).all()


# ------------------------------------------------------------------ MANO


@pytest.mark.parametrize("is_rhand", [True, False])
def test_mano_loads(fake_models, is_rhand):
    m = smplx.create(str(fake_models["root"]), model_type="mano", is_rhand=is_rhand, use_pca=True, num_pca_comps=12)
    assert m.get_num_verts() == 778 and m.get_num_faces() == 1538
    _, j = _check_plausible(_forward(m), max_extent=0.5)
    assert j.shape == (16, 3)  # smplx 0.1.28's MANO does not append the fingertip vertices


def test_mano_left_is_mirrored_right_except_shapedirs_x(fake_models):
    r = _load_pkl(fake_models["mano_right_pkl"])
    left = _load_pkl(fake_models["mano_left_pkl"])
    np.testing.assert_array_equal(left["v_template"], r["v_template"] * [-1, 1, 1])
    sr, sl = np.asarray(r["shapedirs"]), np.asarray(left["shapedirs"])
    np.testing.assert_array_equal(sl[:, 0], sr[:, 0])  # the official file's defect
    np.testing.assert_array_equal(sl[:, 1:], sr[:, 1:])
    # posing: the left hand under the mirrored pose is the mirror of the right hand
    root = str(fake_models["root"])
    mr = smplx.create(root, model_type="mano", is_rhand=True, use_pca=False)
    ml = smplx.create(root, model_type="mano", is_rhand=False, use_pca=False)
    g = torch.Generator().manual_seed(3)
    pose = 0.4 * torch.randn(1, 45, generator=g)
    orient = 0.4 * torch.randn(1, 3, generator=g)
    flip = torch.tensor([1.0, -1.0, -1.0])
    with torch.no_grad():
        vr = mr(hand_pose=pose, global_orient=orient).vertices[0]
        vl = ml(hand_pose=(pose.view(15, 3) * flip).view(1, 45), global_orient=orient * flip).vertices[0]
    torch.testing.assert_close(vl, vr * torch.tensor([-1.0, 1.0, 1.0]), atol=1e-5, rtol=0)
    # ... but not under a shape change along x
    betas = torch.zeros(1, 10)
    betas[0, 1] = 2.0
    with torch.no_grad():
        vr = mr(betas=betas).vertices[0]
        vl = ml(betas=betas).vertices[0]
    assert not torch.allclose(vl, vr * torch.tensor([-1.0, 1.0, 1.0]), atol=1e-4)


# ------------------------------------------------------------------ FLAME


def test_flame_loads_with_contour(fake_models):
    m = smplx.create(
        str(fake_models["root"]),
        model_type="flame",
        use_face_contour=True,
        num_betas=300,
        num_expression_coeffs=100,
    )
    assert m.num_betas == 300 and m.num_expression_coeffs == 100
    assert m.parents.tolist() == [-1, 0, 1, 1, 1]
    _, j = _check_plausible(_forward(m), max_extent=0.6)
    assert j.shape == (5 + 51 + 17, 3)


def test_flame_landmark_files(fake_models):
    s = _load_pkl(fake_models["flame_static_embedding"])
    assert s["lmk_face_idx"].shape == (51,) and s["lmk_b_coords"].shape == (51, 3)
    d = np.load(fake_models["flame_dynamic_embedding"], allow_pickle=True, encoding="latin1")[()]
    assert d["lmk_face_idx"].shape == (79, 17) and d["lmk_b_coords"].shape == (79, 17, 3)
    for idx, bc in ((s["lmk_face_idx"], s["lmk_b_coords"]), (d["lmk_face_idx"], d["lmk_b_coords"])):
        assert idx.max() < 9976
        assert (bc > 0).all()
        np.testing.assert_allclose(bc.sum(-1), 1.0)


# ------------------------------------------------------------------ generic validity


@pytest.mark.parametrize(
    "key,n_joints",
    [
        ("smpl_neutral_pkl", 24),
        ("smplh_neutral_pkl", 52),
        ("smplx_neutral_pkl", 55),
        ("mano_right_pkl", 16),
        ("mano_left_pkl", 16),
        ("flame_neutral_pkl", 5),
    ],
)
def test_arrays_are_valid(fake_models, key, n_joints):
    path = fake_models[key]
    assert _globals(path) <= LEGACY_GLOBALS
    # merged SMPL+H: written by smplx's Python 3 merge script; the rest: Python 2 protocol 2
    assert _protocol(path) == (4 if key == "smplh_neutral_pkl" else 2)
    d = _load_pkl(path)
    v = d["v_template"]
    nv = len(v)
    w = d["weights"]
    assert w.shape == (nv, n_joints)
    assert (w >= 0).all()
    np.testing.assert_allclose(w.sum(1), 1.0)
    nnz = (w > 0).sum(1)
    assert nnz.min() >= 1 and nnz.max() <= 4
    reg = d["J_regressor"]
    reg = reg.toarray() if sp.issparse(reg) else np.asarray(reg)
    assert reg.shape == (n_joints, nv) and (reg >= 0).all()
    np.testing.assert_allclose(reg.sum(1), 1.0)
    rnnz = (reg > 0).sum(1)
    assert rnnz.min() >= 10 and rnnz.max() <= 40
    f = d["f"].astype(np.int64)
    assert f.min() == 0 and f.max() == nv - 1
    assert len(np.unique(f)) == nv  # every vertex used
    assert (f[:, 0] != f[:, 1]).all() and (f[:, 1] != f[:, 2]).all() and (f[:, 0] != f[:, 2]).all()
    assert len(np.unique(np.sort(f, 1), axis=0)) == len(f)
    area = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    assert area.min() > 0
    parents = d["kintree_table"][0].astype(np.int64)
    parents[0] = -1
    assert (parents[1:] < np.arange(1, n_joints)).all()
    assert d["posedirs"].shape == (nv, 3, 9 * (n_joints - 1))
    sd = np.asarray(d["shapedirs"])
    assert 1e-4 < np.abs(sd).max() < 0.1
    assert np.abs(d["posedirs"]).max() < 0.05


def test_extra_joint_vertices_sit_where_expected(fake_models):
    d = _load_pkl(fake_models["smpl_neutral_pkl"])
    v, J = d["v_template"], d["J"]
    head, l_wrist, r_foot = J[15], J[20], J[11]
    assert v[332, 2] > head[2] and v[332, 1] > head[1]  # nose: front of the head
    assert v[2800, 0] > 0 > v[6260, 0]  # leye left, reye right
    assert v[2319, 0] > l_wrist[0]  # left index tip past the wrist
    assert v[6617, 2] > r_foot[2] and v[6617, 0] < 0  # right big toe: front, right
    m = _load_pkl(fake_models["mano_right_pkl"])
    tips = m["v_template"][[744, 320, 443, 554, 671]]
    assert (tips[:, 0] < m["J"][0, 0]).all()  # right hand: fingers to -x
    assert (np.linalg.norm(tips - m["J"][0], axis=1) > 0.08).all()  # tips far from the wrist


def test_deterministic(tmp_path):
    a = fakes.write_mano(tmp_path / "a", "left", seed=5)
    b = fakes.write_mano(tmp_path / "b", "left", seed=5)
    c = fakes.write_mano(tmp_path / "c", "left", seed=6)
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()


def test_write_all_matches_standalone_writers(fake_models, tmp_path):
    # write_all shares generated arrays between files; the bytes must not depend on that
    a = fakes.write_smpl(tmp_path, "female", version="1.0")
    assert a.read_bytes() == fake_models["smpl_female_pkl"].read_bytes()
    b = fakes.write_mano(tmp_path, "left")
    assert b.read_bytes() == fake_models["mano_left_pkl"].read_bytes()


def test_writers_standalone(tmp_path):
    p = fakes.write_smpl(tmp_path, "male", version="1.0", official_name=True)
    assert p.name == "basicmodel_m_lbs_10_207_0_v1.0.0.pkl"
    p = fakes.write_smpl(tmp_path, "neutral", version="1.0", official_name=True)
    assert p.name == "basicModel_neutral_lbs_10_207_0_v1.0.0.pkl"
    p = fakes.write_flame(tmp_path / "fl", "female", official_name=True, landmarks=False)
    assert p.name == "female_model.pkl" and not (p.parent / "flame_static_embedding.pkl").exists()
    p = fakes.write_smplx_kid_template(tmp_path)
    assert np.load(p).shape == (10475, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = _load_pkl(fakes.write_smplh(tmp_path, "female", "pkl", hand_pca=False, official_name=True))
    assert type(d["shapedirs"]).__name__ == "Ch" and "hands_componentsl" not in d
