"""smplcore's torch modules against smplx 0.1.28 on fake official files: vertices and joints ≤ 1e-5 m.

smplx quirks the harness works around to get a reference at all (each is a documented difference):
it caps ``num_betas`` at 10 for files with fewer than 300 components, and it cannot broadcast pose
blocks left at their batch-1 defaults, so every block is passed at the full batch.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

torch = pytest.importorskip("torch")
smplx = pytest.importorskip("smplx")

import smplcore  # noqa: E402
from smplcore.lbs import batch_rodrigues  # noqa: E402

TOL = 1e-5


def _tensor(rng, *shape, scale=0.3):
    return torch.tensor(rng.normal(0.0, scale, shape), dtype=torch.float32)


def _inputs(model, batch, rng, *, layer=False, num_betas=None, num_expr=None, transl=True):
    """Random inputs for every pose block of ``model`` (smplx needs them all at full batch)."""
    params = {"betas": _tensor(rng, batch, num_betas or model.num_betas, scale=1.0)}
    if model.SPEC.has_expression:
        params["expression"] = _tensor(rng, batch, num_expr or model.num_expression_coeffs, scale=1.0)
    for block in model.SPEC.pose_blocks:
        if layer:
            aa = _tensor(rng, batch * block.num_joints, 3, scale=0.5)
            params[block.name] = batch_rodrigues(aa).reshape(batch, block.num_joints, 3, 3)
        else:
            params[block.name] = _tensor(rng, batch, model.setup.pose_width(block.name))
    if transl:
        params["transl"] = _tensor(rng, batch, 3)
    return params


def _compare(fake_models, model_type, options, *, batch=3, layer=False, seed=0, beta_cols=None, **input_kw):
    root = fake_models["root"]
    factory = "build_layer" if layer else "create"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = getattr(smplx, factory)(str(root), model_type=model_type, **options)
        ours = getattr(smplcore, factory)(root, model_type=model_type, **options)
    params = _inputs(ours, batch, np.random.default_rng(seed), layer=layer, num_betas=beta_cols, **input_kw)
    with torch.no_grad():
        expected = ref(**params)
        got = ours(**params)
    assert got.joints.shape == expected.joints.shape
    assert got.vertices.shape == expected.vertices.shape
    dv = (got.vertices - expected.vertices).abs().max().item()
    dj = (got.joints - expected.joints).abs().max().item()
    assert dv <= TOL and dj <= TOL, f"max |Δvertices| {dv:.2e}, max |Δjoints| {dj:.2e}"
    return got


@pytest.mark.parametrize("gender,num_betas", [("neutral", 10), ("neutral", 300), ("male", 10), ("female", 10)])
@pytest.mark.parametrize("batch", [1, 4])
def test_smpl_matches_smplx(fake_models, gender, num_betas, batch):
    out = _compare(fake_models, "smpl", {"gender": gender, "num_betas": num_betas}, batch=batch)
    assert out.joints.shape[1:] == (45, 3)


@pytest.mark.parametrize("use_pca,num_pca_comps", [(True, 6), (True, 12), (True, 45), (False, 6)])
@pytest.mark.parametrize("flat_hand_mean", [False, True])
def test_smplh_pkl_matches_smplx(fake_models, use_pca, num_pca_comps, flat_hand_mean):
    options = {
        "gender": "neutral",
        "ext": "pkl",
        "use_pca": use_pca,
        "num_pca_comps": num_pca_comps,
        "flat_hand_mean": flat_hand_mean,
    }
    out = _compare(fake_models, "smplh", options)
    assert out.joints.shape[1:] == (73, 3)


def test_smplh_amass_npz_16_betas_matches_smplx_on_its_first_10(fake_models):
    # smplx caps num_betas at 10 for this 16-component file; we use all 16 (betas 10..15 zero here).
    options = {"gender": "female", "ext": "npz", "use_pca": False, "num_betas": 16}
    _compare(fake_models, "smplh", options, beta_cols=10)


@pytest.mark.parametrize("ext", ["npz", "pkl"])
@pytest.mark.parametrize("num_betas,num_expr", [(10, 10), (300, 100), (16, 50)])
@pytest.mark.parametrize("use_face_contour", [False, True])
def test_smplx_matches_smplx(fake_models, ext, num_betas, num_expr, use_face_contour):
    options = {
        "gender": "neutral",
        "ext": ext,
        "num_betas": num_betas,
        "num_expression_coeffs": num_expr,
        "use_face_contour": use_face_contour,
    }
    out = _compare(fake_models, "smplx", options)
    assert out.joints.shape[1:] == (144 if use_face_contour else 127, 3)


@pytest.mark.parametrize(
    "use_pca,num_pca_comps,flat_hand_mean", [(True, 6, False), (True, 12, True), (True, 45, False), (False, 6, True)]
)
def test_smplx_hands_match_smplx(fake_models, use_pca, num_pca_comps, flat_hand_mean):
    options = {
        "gender": "neutral",
        "ext": "npz",
        "use_pca": use_pca,
        "num_pca_comps": num_pca_comps,
        "flat_hand_mean": flat_hand_mean,
    }
    _compare(fake_models, "smplx", options, batch=2)


def test_smplx_v10_layout_10_shape_10_expression(fake_models):
    options = {"gender": "male", "ext": "npz", "num_betas": 10, "num_expression_coeffs": 10, "use_face_contour": True}
    _compare(fake_models, "smplx", options)


def test_smplx_kid_template(fake_models):
    options = {
        "gender": "neutral",
        "ext": "npz",
        "age": "kid",
        "kid_template_path": str(fake_models["smplx_kid_template"]),
    }
    out = _compare(fake_models, "smplx", options)
    assert out.betas.shape[1] == 11


def test_smpl_kid_template(fake_models):
    options = {"gender": "neutral", "age": "kid", "kid_template_path": str(fake_models["smpl_kid_template"])}
    _compare(fake_models, "smpl", options)


@pytest.mark.parametrize("is_rhand", [True, False])
@pytest.mark.parametrize("use_pca,num_pca_comps", [(True, 6), (True, 12), (True, 45), (False, 6)])
def test_mano_matches_smplx(fake_models, is_rhand, use_pca, num_pca_comps):
    options = {"is_rhand": is_rhand, "use_pca": use_pca, "num_pca_comps": num_pca_comps}
    out = _compare(fake_models, "mano", options)
    assert out.joints.shape[1:] == (16, 3)


@pytest.mark.parametrize("num_betas,num_expr", [(10, 10), (300, 100)])
@pytest.mark.parametrize("use_face_contour", [False, True])
def test_flame_matches_smplx(fake_models, num_betas, num_expr, use_face_contour):
    options = {"num_betas": num_betas, "num_expression_coeffs": num_expr, "use_face_contour": use_face_contour}
    out = _compare(fake_models, "flame", options)
    assert out.joints.shape[1:] == (73 if use_face_contour else 56, 3)


@pytest.mark.parametrize(
    "model_type,options",
    [
        ("smpl", {}),
        ("smplh", {}),
        ("smplx", {"ext": "npz", "use_face_contour": True}),
        ("mano", {}),
        ("flame", {"use_face_contour": True}),
    ],
)
@pytest.mark.parametrize("batch", [1, 3])
def test_layers_with_rotation_matrices_match_smplx(fake_models, model_type, options, batch):
    _compare(fake_models, model_type, options, layer=True, batch=batch)


def test_contour_turns_with_the_head(fake_models):
    """Large head turns pick other rows of the contour table, and still match smplx."""
    root = fake_models["root"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = smplx.create(str(root), model_type="smplx", ext="npz", use_face_contour=True)
        ours = smplcore.create(root, model_type="smplx", ext="npz", use_face_contour=True)
    rng = np.random.default_rng(3)
    params = _inputs(ours, 5, rng, transl=False)
    params["global_orient"] = torch.tensor([[0.0, a, 0.0] for a in (-1.2, -0.5, 0.0, 0.6, 1.3)])
    with torch.no_grad():
        dj = (ours(**params).joints - ref(**params).joints).abs().max().item()
    assert dj <= TOL
