"""Every path against the one oracle (tests/oracle.py: the plain forward of engine/reference.py in float64),
on vertices and joints: both front ends, every kernel (blocked inference over one and many vertex blocks,
the autograd nodes, the NumPy small-batch skeleton, the reference kernel), Layers, joints-only calls and
rotation matrices, for every model type and option (PCA hands, flat hand mean, contour, kid, expression,
transl), batch 1 and > 1."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from oracle import oracle
from smplcore.engine.reference import rodrigues

torch = pytest.importorskip("torch")

TOL32, TOL64 = 2e-5, 1e-9

MODELS = [
    ("smpl_neutral_pkl", {}),
    ("smplh_neutral_pkl", {"use_pca": True, "num_pca_comps": 12}),
    ("smplh_neutral_pkl", {"use_pca": False, "flat_hand_mean": True}),
    ("smplx_neutral_npz", {"use_face_contour": True, "num_expression_coeffs": 10}),
    ("smplx_neutral_npz", {"use_pca": False, "age": "kid", "kid": True}),
    ("mano_left_pkl", {"use_pca": True}),
    ("flame_neutral_pkl", {"use_face_contour": True}),
    ("open", {}),
]
ORACLE_OPTIONS = (
    "num_betas",
    "num_expression_coeffs",
    "use_pca",
    "num_pca_comps",
    "flat_hand_mean",
    "use_face_contour",
)


def _model_args(fake_models, key, options):
    options = dict(options)
    if options.pop("kid", False):
        options["kid_template_path"] = str(fake_models["root"] / "smplx" / "smplx_kid_template.npy")
    if key == "open":
        return (None,), {"model_type": "open", **options}
    return (fake_models[key],), options


def _params(setup, batch, seed, *, rotmats=False):
    rng = np.random.default_rng(seed)
    params = {"betas": rng.normal(0, 1, (batch, setup.num_betas)), "transl": rng.normal(0, 1, (batch, 3))}
    if setup.spec.has_expression:
        params["expression"] = rng.normal(0, 1, (batch, setup.num_expression_coeffs))
    for block in setup.spec.pose_blocks:
        width = setup.pose_width(block.name)
        params[block.name] = rng.normal(0, 0.5, (batch, width))
        if rotmats:
            params[block.name] = rodrigues(rng.normal(0, 0.5, (batch, block.num_joints, 3)))
    params["global_orient"][0] = 0.0  # exactly zero rotation: the small-angle branch
    return params


def _expected(setup, params, options, rotation_matrices=False):
    opts = {k: v for k, v in options.items() if k in ORACLE_OPTIONS}
    data = setup.data
    if "kid_template_path" in options:  # the kid component is one more shape column
        data = data.replace(shapedirs=np.asarray(setup.shapedirs))
        opts["num_betas"] = setup.num_betas
    if rotation_matrices:
        opts["use_pca"] = False
    return oracle(data, params, rotation_matrices=rotation_matrices, **opts)


def _check(verts, joints, expected, tol):
    ev, ej = expected
    assert joints.shape == ej.shape
    np.testing.assert_allclose(np.asarray(joints, np.float64), ej, atol=tol, rtol=0)
    if verts is not None:
        np.testing.assert_allclose(np.asarray(verts, np.float64), ev, atol=tol, rtol=0)


@pytest.mark.parametrize("key,options", MODELS)
@pytest.mark.parametrize("batch", [1, 5])
@pytest.mark.parametrize("kernel", ["auto", "reference"])
def test_numpy_front_end_equals_the_oracle(fake_models, model_cache, key, options, batch, kernel):
    args, kwargs = _model_args(fake_models, key, options)
    for dtype, tol in ((np.float64, TOL64), (np.float32, TOL32)):
        model = model_cache(smplcore.BodyModel, *args, dtype=dtype, kernel=kernel, **kwargs)
        params = _params(model.setup, batch, seed=batch)
        expected = _expected(model.setup, params, kwargs)
        out = model(**params)
        _check(out.vertices, out.joints, expected, tol)
        joints_only = model(return_verts=False, **params)
        _check(None, joints_only.joints, expected, tol)


@pytest.mark.parametrize("key,options", MODELS)
@pytest.mark.parametrize("batch", [1, 70])  # the skeleton in NumPy (small batch) and in torch
@pytest.mark.parametrize("mode", ["inference", "autograd", "reference"])
def test_torch_front_end_equals_the_oracle(fake_models, model_cache, key, options, batch, mode):
    args, kwargs = _model_args(fake_models, key, options)
    model = model_cache(smplcore.create, *args, kernel="reference" if mode == "reference" else "auto", **kwargs)
    params = _params(model.setup, batch, seed=batch + 1)
    expected = _expected(model.setup, params, kwargs)
    tensors = {k: torch.tensor(v, dtype=torch.float32, requires_grad=mode == "autograd") for k, v in params.items()}
    with torch.set_grad_enabled(mode != "inference"):
        out = model(**tensors)
        joints_only = model(return_verts=False, **tensors)
    _check(out.vertices.detach().numpy(), out.joints.detach().numpy(), expected, TOL32 * 2)
    _check(None, joints_only.joints.detach().numpy(), expected, TOL32 * 2)


@pytest.mark.parametrize("key,options", [m for m in MODELS if m[0] != "open"])
def test_layers_with_rotation_matrices_equal_the_oracle(fake_models, key, options):
    args, kwargs = _model_args(fake_models, key, options)
    layer = smplcore.build_layer(*args, **kwargs)
    params = _params(layer.setup, 3, seed=7, rotmats=True)
    expected = _expected(layer.setup, params, kwargs, rotation_matrices=True)
    with torch.no_grad():
        out = layer(**{k: torch.tensor(v, dtype=torch.float32) for k, v in params.items()})
    _check(out.vertices.numpy(), out.joints.numpy(), expected, TOL32 * 2)


@pytest.mark.parametrize("key", ["smpl_neutral_pkl", "smplx_neutral_npz"])
def test_many_vertex_blocks_and_float64_equal_the_oracle(fake_models, monkeypatch, key):
    from smplcore.engine.kernels import blocked, skin_autograd

    monkeypatch.setattr(blocked, "_PLANE_VALUES", 9 * 100)  # blocks of ~100 vertices at B = 9
    monkeypatch.setattr(blocked, "_MIN_BLOCK", 1)
    monkeypatch.setattr(blocked, "_APPLY_VALUES", 2 * 100)
    monkeypatch.setattr(skin_autograd, "_CHUNK_VALUES", 300)
    model = smplcore.create(fake_models[key], dtype=torch.float64, use_face_contour="smplx" in key)
    params = _params(model.setup, 9, seed=3)
    expected = _expected(model.setup, params, {"use_face_contour": "smplx" in key})
    for grad in (False, True):
        tensors = {k: torch.tensor(v, requires_grad=grad) for k, v in params.items()}
        out = model(**tensors)
        _check(out.vertices.detach().numpy(), out.joints.detach().numpy(), expected, TOL64)


@pytest.mark.parametrize("key", ["smplx_neutral_npz", "open"])
def test_gradients_of_every_kernel_agree_and_are_finite_at_zero_pose(fake_models, key):
    args, kwargs = _model_args(fake_models, key, {})
    grads = {}
    for kernel in ("auto", "reference"):
        model = smplcore.create(*args, dtype=torch.float64, kernel=kernel, **kwargs)
        params = {k: torch.tensor(v, requires_grad=True) for k, v in _params(model.setup, 2, seed=4).items()}
        params["body_pose"].data.zero_()
        out = model(**params)
        ((out.vertices**2).sum() + (out.joints**3).sum()).backward()
        grads[kernel] = {k: v.grad for k, v in params.items()}
    for name, g in grads["auto"].items():
        assert torch.isfinite(g).all(), name
        torch.testing.assert_close(g, grads["reference"][name], atol=1e-8, rtol=1e-7)  # float64, other summation order


def test_the_reference_kernel_differentiates_the_model_arrays(fake_models):
    model = smplcore.create(fake_models["smpl_neutral_pkl"], dtype=torch.float64)
    model.shapedirs.requires_grad_(True)
    out = model(betas=torch.ones(1, 10, dtype=torch.float64))
    out.vertices.sum().backward()
    assert model.shapedirs.grad is not None and model.shapedirs.grad.abs().sum() > 0


def test_a_forced_kernel_runs_or_raises(fake_models):
    model = smplcore.create(fake_models["smpl_neutral_pkl"])
    with pytest.raises(ValueError, match="kernel='blocked' records no gradients"):
        model(betas=torch.zeros(1, 10, requires_grad=True), kernel="blocked")
    with pytest.raises(ValueError, match="kernel: expected one of"):
        smplcore.create(fake_models["smpl_neutral_pkl"], kernel="fast")
    with pytest.raises(ValueError, match="'autograd' is for torch tensors"):
        smplcore.BodyModel(model_type="open", kernel="autograd")(betas=np.zeros((1, 10)))
