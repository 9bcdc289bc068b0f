"""fit_vertices: exact Jacobians, recovery of known parameters, options, NumPy == torch, bad inputs."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore import fit
from smplcore.errors import ShapeError
from smplcore.fit.body import FitBody, pose_points

MODEL_TYPES = ["smpl", "smplh", "smplx", "mano", "flame", "open"]


def _model(fake_models, model_type, **kw):
    if model_type == "open":
        return smplcore.BodyModel(model_type="open", dtype=np.float64, **kw)
    return smplcore.BodyModel(fake_models["root"], model_type=model_type, dtype=np.float64, **kw)


def _random_params(model, batch, rng, scale=0.3, transl=True):
    body = FitBody.from_model(model)
    params = {b.name: rng.normal(0, scale, (batch, b.width)) for b in body.blocks}
    params["betas"] = rng.normal(0, 1, (batch, model.num_betas))
    if body.num_expression:
        params["expression"] = rng.normal(0, 1, (batch, body.num_expression))
    if transl:
        params["transl"] = rng.normal(0, 0.5, (batch, 3))
    return params


def _subset(model, size=500):
    count = model.setup.data.v_template.shape[0]
    return np.unique(np.linspace(0, count - 1, min(size, count)).astype(int))


@pytest.mark.parametrize("model_type", MODEL_TYPES)
def test_jacobian_matches_finite_differences(fake_models, model_type):
    model = _model(fake_models, model_type)
    body = FitBody.from_model(model)
    rng = np.random.default_rng(0)
    ids = np.sort(rng.choice(body.num_vertices + body.num_joints, 60, replace=False))
    pts = body.points(ids)
    theta = rng.normal(0, 0.4, (2, body.num_joints, 3))
    coeffs, transl = rng.normal(0, 1, (2, body.num_coeffs)), rng.normal(0, 1, (2, 3))
    jac = pose_points(body, pts, theta, coeffs, transl, jacobian=True).jacobian
    jac = jac.reshape(2, -1, jac.shape[-1])
    x0 = np.concatenate([theta.reshape(2, -1), coeffs, transl], axis=1)
    nj3, k = theta[0].size, coeffs.shape[1]

    def f(x):
        return pose_points(body, pts, x[:, :nj3].reshape(theta.shape), x[:, nj3 : nj3 + k], x[:, -3:]).points

    fd = np.empty_like(jac)
    eps = 1e-6
    for c in range(x0.shape[1]):
        step = np.zeros_like(x0)
        step[:, c] = eps
        fd[:, :, c] = ((f(x0 + step) - f(x0 - step)) / (2 * eps)).reshape(2, -1)
    assert np.abs(fd - jac).max() < 1e-7 * max(1.0, np.abs(jac).max())


@pytest.mark.parametrize("model_type", MODEL_TYPES)
def test_posed_points_match_the_model(fake_models, model_type):
    model = _model(fake_models, model_type)
    body = FitBody.from_model(model)
    params = _random_params(model, 2, np.random.default_rng(1))
    out = model(**params)
    state = fit.result.params_to_state(body, params, 2)
    pts = body.points(np.arange(body.num_vertices + body.num_joints))
    posed = pose_points(body, pts, body.full_pose(state.pose), state.coeffs, state.transl).points
    atol = 1e-6 if model_type == "open" else 1e-10  # the open model's forward keeps some float32 arrays
    np.testing.assert_allclose(posed[:, : body.num_vertices], out.vertices, atol=atol)
    np.testing.assert_allclose(posed[:, body.num_vertices :], out.joints[:, : body.num_joints], atol=atol)


@pytest.mark.parametrize("model_type", MODEL_TYPES)
def test_recovers_known_parameters_from_exact_vertices(fake_models, model_type):
    model = _model(fake_models, model_type)
    params = _random_params(model, 2, np.random.default_rng(2))
    ids = _subset(model)
    target = model(**params).vertices
    r = fit.fit_vertices(model, target[:, ids], vertex_ids=ids)
    assert r.converged.all()
    assert r.vertex_error.max() < 1e-6
    full = np.linalg.norm(model(**r.params).vertices - target, axis=-1).mean(1)
    assert full.max() < 1e-3  # every vertex, not just the fitted ones, within 1 mm
    np.testing.assert_allclose(r.params["betas"], params["betas"], atol=1e-4)


def test_recovers_the_open_model_from_its_whole_mesh():
    model = smplcore.BodyModel(model_type="open")  # float32, as users run it
    params = _random_params(model, 1, np.random.default_rng(3))
    target = model(**params).vertices
    r = fit.fit_vertices(model, target)
    assert r.converged.all() and r.vertex_error.max() < 1e-4
    assert r.params["betas"].dtype == np.float32
    np.testing.assert_allclose(model(**r.params).vertices, target, atol=1e-4)


def test_pca_hands_are_fitted_as_pca_coefficients(fake_models):
    model = _model(fake_models, "smplh", use_pca=True, num_pca_comps=6)
    params = _random_params(model, 1, np.random.default_rng(4))
    assert params["left_hand_pose"].shape == (1, 6)
    target = model(**params).vertices
    ids = _subset(model)
    r = fit.fit_vertices(model, target[:, ids], vertex_ids=ids)
    assert r.params["left_hand_pose"].shape == (1, 6)
    assert np.linalg.norm(model(**r.params).vertices - target, axis=-1).mean() < 1e-3


def test_shared_betas_over_a_batch(fake_models):
    model = _model(fake_models, "smpl")
    rng = np.random.default_rng(5)
    params = _random_params(model, 3, rng)
    params["betas"] = np.repeat(params["betas"][:1], 3, axis=0)
    target = model(**params).vertices
    # noise makes per-frame betas differ; shared ones must be one vector
    noisy = target + rng.normal(0, 0.002, target.shape)
    ids = _subset(model, 400)
    r = fit.fit_vertices(model, noisy[:, ids], vertex_ids=ids, share_betas=True)
    betas = r.params["betas"]
    np.testing.assert_allclose(betas, np.repeat(betas[:1], 3, axis=0), atol=1e-12)
    exact = fit.fit_vertices(model, target[:, ids], vertex_ids=ids, share_betas=True)
    np.testing.assert_allclose(exact.params["betas"], params["betas"], atol=1e-4)
    assert exact.vertex_error.max() < 1e-6


def test_fixed_betas_and_no_translation(fake_models):
    model = _model(fake_models, "smpl")
    params = _random_params(model, 2, np.random.default_rng(6), transl=False)
    target = model(**params).vertices
    ids = _subset(model, 400)
    fixed = {"betas": params["betas"], "fit_betas": False, "fit_transl": False}
    r = fit.fit_vertices(model, target[:, ids], vertex_ids=ids, **fixed)
    np.testing.assert_array_equal(r.params["betas"], params["betas"])
    np.testing.assert_array_equal(r.params["transl"], np.zeros((2, 3)))
    assert r.vertex_error.max() < 1e-6


def test_zero_weights_ignore_corrupted_vertices(fake_models):
    model = _model(fake_models, "smpl")
    params = _random_params(model, 1, np.random.default_rng(7))
    ids = _subset(model, 400)
    target = model(**params).vertices[:, ids].copy()
    weights = np.ones(len(ids))
    target[:, :40] += 0.2
    weights[:40] = 0.0
    r = fit.fit_vertices(model, target, vertex_ids=ids, vertex_weights=weights)
    err = np.linalg.norm(model(**r.params).vertices[:, ids] - target, axis=-1)[0]
    assert err[40:].max() < 1e-5 and err[:40].min() > 0.1


def test_joint_targets_are_fitted_with_the_vertices(fake_models):
    model = _model(fake_models, "smpl")
    params = _random_params(model, 1, np.random.default_rng(8))
    out = model(**params)
    ids = _subset(model, 300)
    r = fit.fit_vertices(model, out.vertices[:, ids], joints=out.joints[:, :24], vertex_ids=ids)
    assert r.joint_error.max() < 1e-6 and r.vertex_error.max() < 1e-6


def test_shape_prior_shrinks_betas(fake_models):
    model = _model(fake_models, "smpl")
    params = _random_params(model, 1, np.random.default_rng(9))
    ids = _subset(model, 300)
    target = model(**params).vertices[:, ids]
    free = fit.fit_vertices(model, target, vertex_ids=ids)
    shrunk = fit.fit_vertices(model, target, vertex_ids=ids, shape_prior=10.0)
    assert np.linalg.norm(shrunk.params["betas"]) < 0.5 * np.linalg.norm(free.params["betas"])


def test_numpy_and_torch_models_give_the_same_fit(fake_models):
    torch = pytest.importorskip("torch")
    numpy_model = smplcore.BodyModel(fake_models["root"], model_type="smpl", dtype=np.float64)
    torch_model = smplcore.create(fake_models["root"], model_type="smpl", dtype=torch.float64)
    params = _random_params(numpy_model, 2, np.random.default_rng(10))
    ids = _subset(numpy_model, 300)
    target = numpy_model(**params).vertices[:, ids]
    a = fit.fit_vertices(numpy_model, target, vertex_ids=ids)
    b = fit.fit_vertices(torch_model, torch.as_tensor(target), vertex_ids=ids)
    for name, value in a.params.items():
        assert isinstance(b.params[name], torch.Tensor)
        np.testing.assert_allclose(b.params[name].numpy(), value, atol=1e-9)
    verts = torch_model(**b.params).vertices.detach().numpy()
    np.testing.assert_allclose(verts[:, ids], target, atol=1e-6)


def test_bad_inputs_name_the_argument(fake_models):
    model = smplcore.BodyModel(model_type="open")
    n = model.setup.data.v_template.shape[0]
    with pytest.raises(ShapeError, match="vertices"):
        fit.fit_vertices(model, np.zeros((2, n - 1, 3)))
    bad = np.zeros((1, n, 3))
    bad[0, 5, 1] = np.nan
    with pytest.raises(ValueError, match="vertices: 1 non-finite"):
        fit.fit_vertices(model, bad)
    with pytest.raises(ValueError, match="vertex_weights"):
        fit.fit_vertices(model, np.zeros((1, n, 3)), vertex_weights=-np.ones(n))
    with pytest.raises(ValueError, match="vertex_ids"):
        fit.fit_vertices(model, np.zeros((1, 2, 3)), vertex_ids=[0, n])
    with pytest.raises(ShapeError, match="joints"):
        fit.fit_vertices(model, np.zeros((1, n, 3)), joints=np.zeros((1, 30, 3)))
    with pytest.raises(TypeError, match="model"):
        fit.fit_vertices(object(), np.zeros((1, n, 3)))


def test_float32_model_recovers_a_whole_smplx_mesh(fake_models):
    model = smplcore.BodyModel(fake_models["root"], model_type="smplx", use_pca=False)  # float32 products
    params = _random_params(model, 2, np.random.default_rng(11), scale=0.2)
    target = model(**params).vertices
    r = fit.fit_vertices(model, target)
    assert r.converged.all()
    err = np.linalg.norm(model(**r.params).vertices - target, axis=-1).mean(1)
    assert err.max() < 1e-4  # 0.1 mm: float32 resolution, far below the 1 mm bar


def test_noisy_targets_reach_the_whole_mesh_optimum(fake_models):
    """The subset Gauss-Newton matrix only changes the path: the result is a stationary point of the
    objective over every vertex (the exact dense solver from there gains nothing)."""
    from smplcore.fit.solver import Objective, levenberg_marquardt
    from smplcore.fit.vertices import coefficient_masks

    model = _model(fake_models, "smpl")
    rng = np.random.default_rng(12)
    params = _random_params(model, 2, rng)
    target = model(**params).vertices + rng.normal(0, 0.003, (2, 6890, 3))
    r = fit.fit_vertices(model, target, tol=1e-10)
    body = FitBody.from_model(model)
    state = fit.result.params_to_state(body, {k: np.asarray(v, np.float64) for k, v in r.params.items()}, 2)
    free, shared = coefficient_masks(body, True, True, False)
    obj = Objective(body.points(np.arange(body.num_vertices)), target, np.ones((2, 6890)), free, shared)
    polished, cost, _, _ = levenberg_marquardt(body, obj, state, max_iter=3, tol=1e-12)
    start = fit.solver.residual_cost(body, obj, state)
    assert np.all(start - cost <= 1e-6 * start)
    np.testing.assert_allclose(polished.pose, state.pose, atol=1e-4)


def test_threads_give_the_same_fit(fake_models):
    model = _model(fake_models, "smpl")
    rng = np.random.default_rng(13)
    target = model(**_random_params(model, 40, rng)).vertices
    one = fit.fit_vertices(model, target, workers=1)
    two = fit.fit_vertices(model, target, workers=2)
    for name in one.params:  # the same iterations; products over chunks of bodies round differently
        np.testing.assert_allclose(one.params[name], two.params[name], atol=1e-9)
    np.testing.assert_allclose(one.vertex_error, two.vertex_error, atol=1e-9)


def test_regressed_joints_need_every_vertex_the_regressor_reads(fake_models):
    from smplcore.fit.vertices import regressed_joints

    model = _model(fake_models, "smpl")
    body = FitBody.from_model(model)
    out = model(**_random_params(model, 2, np.random.default_rng(14)))
    ids = np.arange(body.num_vertices)
    reg = model.setup.data.J_regressor
    want = np.einsum("jv,bvc->bjc", reg.toarray() if hasattr(reg, "toarray") else reg, out.vertices)
    np.testing.assert_allclose(regressed_joints(body, ids, out.vertices, np.ones((2, len(ids)))), want, atol=1e-12)
    needed = np.unique(body.regressor.indices)
    weights = np.ones((2, len(ids)))
    weights[1, needed[0]] = 0.0  # a vertex the regressor reads is ignored by one body
    assert regressed_joints(body, ids, out.vertices, weights) is None
    fewer = np.setdiff1d(ids, needed[:1])
    assert regressed_joints(body, fewer, out.vertices[:, fewer], np.ones((2, len(fewer)))) is None


def test_closed_form_start_of_the_open_model():
    """The open model's collars move no vertex most: their parts take their points by main joint and the
    regressed joints at the ends of their bones. The closed form alone (max_iter=0) lands within ~5 mm on
    random poses after its default three rounds (it was 23 mm when parts took only points skinned at least
    half to them; 9 mm when each round turned the parts' rest points rather than their posed ones, whose
    blended skinning biased the rotations), and refinement then needs a few iterations."""
    model = smplcore.BodyModel(model_type="open", dtype=np.float32)
    rng = np.random.default_rng(15)
    params = {
        "global_orient": rng.normal(0, 0.6, (32, 3)),
        "body_pose": rng.normal(0, 0.25, (32, 69)),
        "betas": rng.normal(0, 1, (32, 10)),
    }
    target = model(**params).vertices
    start = fit.fit_vertices(model, target, max_iter=0)
    assert start.vertex_error.mean() < 0.0055, start.vertex_error.mean()
    exact = fit.fit_vertices(model, target)
    assert exact.vertex_error.max() < 1e-5 and exact.iterations <= 8


def test_a_dual_quaternion_model_is_refused_by_name():
    model = smplcore.BodyModel(model_type="open", skinning="dqs")
    with pytest.raises(ValueError, match="skinning='lbs'"):
        fit.fit_vertices(model, np.zeros((1, 13380, 3)))


@pytest.mark.parametrize("model_type", ["smpl", "smplx"])
def test_closed_form_rounds_converge_to_exact_parameters(fake_models, model_type):
    """Each round turns a part by the rotation from its posed (skinned) points to their targets, so the
    exact parameters are a fixed point however blended the skinning; from near them (0.01 rad off), rounds
    on the fit's own sample of points reach them (turning the rest points instead drifts 0.06–0.1 rad off)."""
    from smplcore.fit.initialize import initialize
    from smplcore.fit.result import params_to_state
    from smplcore.fit.solver import Objective
    from smplcore.fit.vertices import spread_subset

    model = _model(fake_models, model_type)
    body = FitBody.from_model(model)
    params = _random_params(model, 3, np.random.default_rng(16))
    ids = spread_subset(body, np.arange(body.num_vertices), 64, 8)
    target = model(**params).vertices[:, ids]
    free = np.ones(body.num_coeffs, bool)
    obj = Objective(body.points(ids), target, np.ones((3, len(ids))), free, np.zeros_like(free), True, 0.0, None)
    truth = params_to_state(body, params, 3)
    start = truth.copy()
    start.pose += np.random.default_rng(19).normal(0, 0.01, start.pose.shape)
    after = initialize(body, obj, start, iterations=12)
    np.testing.assert_allclose(after.pose, truth.pose, atol=1e-6)
    np.testing.assert_allclose(after.coeffs, truth.coeffs, atol=1e-5)


def test_closed_form_rounds_never_raise_the_cost():
    """The open model's blended spine, neck and collars let the shape absorb a part's misfit, and a round can
    overshoot: each body keeps its best round, so more rounds never fit the points worse."""
    from smplcore.fit import dense
    from smplcore.fit.initialize import initialize
    from smplcore.fit.result import params_to_state
    from smplcore.fit.solver import Objective

    model = smplcore.BodyModel(model_type="open")
    body = FitBody.from_model(model)
    params = _random_params(model, 16, np.random.default_rng(17), transl=False)
    ids = _subset(model, 300)
    target = model(**params).vertices[:, ids]
    free = np.ones(body.num_coeffs, bool)
    obj = Objective(body.points(ids), target, np.ones((16, len(ids))), free, np.zeros_like(free), True, 0.0, None)
    arrays = dense.dense_points(body, obj.points)
    costs = []
    for rounds in (1, 2, 3, 5, 8):
        s = initialize(body, obj, params_to_state(body, {}, 16), iterations=rounds)
        posed = dense.pose(body, arrays, body.full_pose(s.pose), s.coeffs, s.transl).points
        costs.append(((posed - np.moveaxis(target, 0, -1)) ** 2).sum((0, 1)))
    assert np.all(np.diff(costs, axis=0) <= 1e-12)
    assert costs[-1].mean() < 0.5 * costs[0].mean()


@pytest.mark.parametrize("model_type", ["smpl", "open"])
def test_a_fit_on_the_sample_of_points_alone(fake_models, model_type):
    """exact=False stops after the sample's iterations: millimetres from the exact fit, without posing the
    whole mesh; its errors are measured (once) when first read and equal the model's distances."""
    model = _model(fake_models, model_type)
    params = _random_params(model, 8, np.random.default_rng(18))
    target = model(**params).vertices
    closed = fit.fit_vertices(model, target, max_iter=0, init_iterations=1)
    target = np.array(target)
    r = fit.fit_vertices(model, target, max_iter=1, init_iterations=1, exact=False)
    assert "measured on access" in repr(r)
    given = target.copy()
    target += 1.0  # the caller's array changes before the errors are read: they are still the fit's
    fitted = model(**r.params).vertices
    np.testing.assert_allclose(r.vertex_error, np.linalg.norm(fitted - given, axis=-1).mean(1), rtol=1e-9)
    target = given
    assert "measured on access" not in repr(r)
    assert r.iterations == 1 and r.converged.shape == (8,)
    assert r.vertex_error.mean() < 0.006 and r.vertex_error.mean() < 0.4 * closed.vertex_error.mean()
    more = fit.fit_vertices(model, target, max_iter=30, exact=False)  # the sample's optimum: exact targets
    assert more.vertex_error.max() < 1e-4 and more.all_converged


def test_errors_measured_on_first_read_only():
    from smplcore.fit.result import FitResult

    calls = []

    def measure():
        calls.append(1)
        return np.array([1.0]), np.array([2.0])

    r = FitResult(params={}, measure=measure)
    r.vertex_error = np.array([5.0])  # set before measuring: the joints' error is still measured
    assert not calls
    assert r.joint_error[0] == 2.0 and r.vertex_error[0] == 5.0 and len(calls) == 1
    assert r.joint_error[0] == 2.0 and len(calls) == 1
