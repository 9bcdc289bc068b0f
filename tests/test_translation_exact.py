"""A translation moves every vertex by exactly itself, far from the origin too (issue 27, item 4).

Skinning weights stored in float32 sum to 1 only within ~1e-7; folding the translation into the skinning
transforms multiplies it by that sum, so a float64 body 1,000 km away came out 13 cm off. Every kernel and
front end must match the oracle (which adds the translation after skinning) to float64 rounding of |transl|.
"""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from oracle import oracle

torch = pytest.importorskip("torch")

FAR = [1e3, 1e6]  # metres


def _params(model_setup, transl, seed=0):
    rng = np.random.default_rng(seed)
    params = {"betas": rng.normal(0, 1, (2, model_setup.num_betas))}
    params["transl"] = np.array([[transl, -transl, transl]] * 2)
    for block in model_setup.spec.pose_blocks:
        params[block.name] = rng.normal(0, 0.3, (2, model_setup.pose_width(block.name)))
    return params


def _tolerance(transl):
    return 1e-9 + 1e-12 * transl  # float64: rounding of |transl| is ~2e-16 |transl|


def test_the_open_model_weights_do_not_sum_to_one_in_float64():
    """The premise: the packaged weights are float32-stored, so the fix must not assume exact sums."""
    weights = np.asarray(smplcore.BodyModel(model_type="open", dtype=np.float64).setup.data.weights, np.float64)
    assert np.abs(weights.sum(axis=1) - 1).max() > 1e-9


@pytest.mark.parametrize("transl", FAR)
@pytest.mark.parametrize("kernel", ["auto", "reference"])
@pytest.mark.parametrize("skinning", ["lbs", "dqs"])
def test_numpy_front_end_far_away_equals_the_oracle(transl, kernel, skinning):
    model = smplcore.BodyModel(model_type="open", dtype=np.float64, kernel=kernel, skinning=skinning)
    params = _params(model.setup, transl)
    ev, ej = oracle(model.setup.data, params, skinning=skinning)
    out = model(**params)
    np.testing.assert_allclose(out.vertices, ev, atol=_tolerance(transl), rtol=0)
    np.testing.assert_allclose(out.joints, ej, atol=_tolerance(transl), rtol=0)


@pytest.mark.parametrize("transl", FAR)
@pytest.mark.parametrize("mode", ["inference", "autograd", "reference"])
@pytest.mark.parametrize("skinning", ["lbs", "dqs"])
def test_torch_front_end_far_away_equals_the_oracle(transl, mode, skinning):
    model = smplcore.create(
        model_type="open", dtype=torch.float64, kernel="reference" if mode == "reference" else "auto", skinning=skinning
    )
    params = _params(model.setup, transl)
    ev, ej = oracle(model.setup.data, params, skinning=skinning)
    tensors = {k: torch.tensor(v, requires_grad=mode == "autograd") for k, v in params.items()}
    with torch.set_grad_enabled(mode != "inference"):
        out = model(**tensors)
    np.testing.assert_allclose(out.vertices.detach().numpy(), ev, atol=_tolerance(transl), rtol=0)
    np.testing.assert_allclose(out.joints.detach().numpy(), ej, atol=_tolerance(transl), rtol=0)


@pytest.mark.parametrize("gradients", [False, True])
def test_the_compiled_operators_far_away_equal_the_oracle(gradients):
    """The custom-operator path (what a ``torch.compile``-d forward runs), called directly."""
    from smplcore.engine.kernels import ops
    from smplcore.engine.reference import rodrigues

    model = smplcore.create(model_type="open", dtype=torch.float64)
    params = _params(model.setup, 1e6)
    ev, _ = oracle(model.setup.data, params)
    rotvecs = np.concatenate([params[b.name] for b in model.setup.spec.pose_blocks], axis=1).reshape(2, -1, 3)
    coeffs = torch.tensor(params["betas"], requires_grad=gradients)
    rotmats = torch.tensor(rodrigues(rotvecs))
    source = model.source
    if source is None or source.handle is None:
        pytest.skip("this front end registers no operator handle")
    verts, _ = ops.forward(
        source.handle,
        source.latest_arrays(),
        coeffs,
        rotmats,
        translation=torch.tensor(params["transl"]),
        gradients=gradients,
    )
    np.testing.assert_allclose(verts.detach().numpy(), ev, atol=_tolerance(1e6), rtol=0)


def test_float32_models_still_fold_the_translation_within_float32_rounding():
    model = smplcore.BodyModel(model_type="open")
    params = _params(model.setup, 1e3)
    ev, _ = oracle(model.setup.data, params)
    out = model(**params)
    np.testing.assert_allclose(out.vertices, ev, atol=1e3 * 4e-7, rtol=0)


@pytest.mark.parametrize("transl", FAR)
def test_fit_vertices_reports_the_models_actual_error_far_away(transl):
    from smplcore import fit

    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    params = _params(model.setup, transl, seed=3)
    params = {k: v[:1] for k, v in params.items()}
    target = oracle(model.setup.data, params)[0]  # the true body, far away
    result = fit.fit_vertices(model, target)
    actual = np.linalg.norm(model(**result.params).vertices - target, axis=-1).mean(axis=-1)
    reported = np.asarray(result.vertex_error)
    assert np.isfinite(reported).all()
    np.testing.assert_allclose(reported, actual, atol=1e-9 + 1e-12 * transl, rtol=1e-6)
    assert actual[0] < 1e-6 + 1e-12 * transl
