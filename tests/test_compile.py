"""``torch.compile(model, fullgraph=True)`` and ``torch.export`` of the forward: exact, with and without
autograd. Inductor (what users run) on SMPL-X, the model with every feature; the graph capture itself
(``aot_eager``, fast) on every other model type."""

from __future__ import annotations

import pytest

import smplcore

torch = pytest.importorskip("torch")

pytestmark = pytest.mark.slow  # compilation: a sixth of the suite's time


def _inputs(model, batch, grad=False):
    gen = torch.Generator().manual_seed(batch)
    params = {
        "betas": torch.randn(batch, model.num_betas, generator=gen),
        "transl": torch.randn(batch, 3, generator=gen),
    }
    if model.SPEC.has_expression:
        params["expression"] = torch.randn(batch, model.num_expression_coeffs, generator=gen)
    for block in model.SPEC.pose_blocks:
        params[block.name] = 0.4 * torch.randn(batch, model.setup.pose_width(block.name), generator=gen)
    return {k: v.requires_grad_(grad) for k, v in params.items()}


def _model(fake_models, model_type, **options):
    return smplcore.create(None if model_type == "open" else fake_models["root"], model_type=model_type, **options)


def _compare(compiled, eager, params):
    a, b = compiled(**params), eager(**params)
    assert (a.vertices - b.vertices).abs().max() < 1e-5 and (a.joints - b.joints).abs().max() < 1e-5
    return a, b


def test_inductor_fullgraph_smplx_is_exact_with_and_without_autograd(fake_models):
    torch._dynamo.reset()
    model = _model(fake_models, "smplx", use_face_contour=True)
    compiled = torch.compile(model, fullgraph=True)
    with torch.no_grad():
        _compare(compiled, model, _inputs(model, 3))
    params = _inputs(model, 2, grad=True)
    a, _ = _compare(compiled, model, params)
    (a.vertices.square().sum() + a.joints.sum()).backward()
    compiled_grad = {k: v.grad.clone() for k, v in params.items()}
    for v in params.values():
        v.grad = None
    b = model(**params)
    (b.vertices.square().sum() + b.joints.sum()).backward()
    for k, v in params.items():
        torch.testing.assert_close(compiled_grad[k], v.grad, atol=1e-3, rtol=1e-4)
    assert a.v_shaped is not None and a.v_shaped.shape == (2, 10475, 3)


@pytest.mark.parametrize(
    "model_type,options",
    [("smpl", {}), ("smplh", {}), ("mano", {}), ("flame", {"use_face_contour": True}), ("open", {})],
)
def test_every_model_compiles_in_one_graph(fake_models, model_type, options):
    torch._dynamo.reset()
    model = _model(fake_models, model_type, **options)
    compiled = torch.compile(model, fullgraph=True, backend="aot_eager")
    with torch.no_grad():
        _compare(compiled, model, _inputs(model, 2))
    a, _ = _compare(compiled, model, _inputs(model, 2, grad=True))
    assert a.vertices.requires_grad


def test_torch_export_with_a_dynamic_batch(fake_models):
    model = _model(fake_models, "smpl")

    class Forward(torch.nn.Module):
        def __init__(self, body):
            super().__init__()
            self.body = body

        def forward(self, betas, body_pose, global_orient, transl):
            out = self.body(betas=betas, body_pose=body_pose, global_orient=global_orient, transl=transl)
            return out.vertices, out.joints

    wrapper = Forward(model)
    example = {k: v for k, v in _inputs(model, 3).items()}
    batch = torch.export.Dim("batch", min=2, max=4096)
    program = torch.export.export(wrapper, (), kwargs=example, dynamic_shapes={k: {0: batch} for k in example})
    for size in (2, 7):
        params = _inputs(model, size)
        with torch.no_grad():
            verts, joints = program.module()(**params)
            expected = model(**params)
        assert verts.shape == (size, 6890, 3)
        assert (verts - expected.vertices).abs().max() < 1e-5 and (joints - expected.joints).abs().max() < 1e-5


def test_torch_func_transforms_run_the_plain_kernel(fake_models):
    model = _model(fake_models, "open")
    params = _inputs(model, 1)

    def loss(betas):
        return model(**{**params, "betas": betas}).vertices.square().sum()

    grad = torch.func.grad(loss)(params["betas"])
    betas = params["betas"].clone().requires_grad_(True)
    loss(betas).backward()
    torch.testing.assert_close(grad, betas.grad, atol=1e-4, rtol=1e-5)


def _recorded_ops(model, params):
    """The smplcore custom operators in the graph that ``torch.compile`` captures for ``model(**params)``."""
    seen = set()

    def backend(gm, example_inputs):
        seen.update(str(n.target).removesuffix(".default") for n in gm.graph.nodes if "smplcore" in str(n.target))
        return gm.forward

    torch._dynamo.reset()
    torch.compile(model, fullgraph=True, backend=backend)(**params)
    return seen


def test_compiled_forward_calls_the_fast_kernels_as_operators(fake_models):
    model = _model(fake_models, "smpl")
    with torch.no_grad():
        assert _recorded_ops(model, _inputs(model, 2)) == {"smplcore.joint_basis", "smplcore.skin_blocked"}
    assert _recorded_ops(model, _inputs(model, 2, grad=True)) == {
        "smplcore.joint_basis",
        "smplcore.blend",
        "smplcore.skin",
    }
    assert not _recorded_ops(
        smplcore.create(fake_models["root"], model_type="smpl", kernel="reference"), _inputs(model, 2)
    )


def test_buffer_edits_reach_a_compiled_forward(fake_models):
    """The operators read the model's current arrays at every call: an edit after compiling counts."""
    torch._dynamo.reset()
    model = _model(fake_models, "mano")
    compiled = torch.compile(model, fullgraph=True, backend="aot_eager")
    params = _inputs(model, 2)
    with torch.no_grad():
        before = compiled(**params).vertices
        model.shapedirs[:, 0, :] *= -1  # smplx users' MANO left-hand fix
        after, expected = compiled(**params), model(**params)
    assert (after.vertices - before).abs().max() > 1e-3
    assert (after.vertices - expected.vertices).abs().max() < 1e-5
    assert (after.joints - expected.joints).abs().max() < 1e-5


def test_a_copied_model_has_its_own_arrays_in_the_operators(fake_models):
    import copy

    model = _model(fake_models, "smpl")
    twin = copy.deepcopy(model)
    assert twin.source.handle != model.source.handle
    with torch.no_grad():
        twin.v_template += 0.5
        params = _inputs(model, 1)
        a = torch.compile(twin, fullgraph=True, backend="aot_eager")(**params)
        b = torch.compile(model, fullgraph=True, backend="aot_eager")(**params)
    assert torch.allclose(a.vertices - 0.5, b.vertices, atol=1e-5)


def test_the_operators_fake_kernels_match_their_real_ones(fake_models):
    model = _model(fake_models, "smpl")
    handle = model.source.handle
    gen = torch.Generator().manual_seed(0)
    feats = torch.randn(2, 1 + 10 + 207, generator=gen)
    transforms = torch.randn(2, 24, 12, generator=gen)
    rest = torch.randn(2, 3, 6890, generator=gen, requires_grad=True)
    ids = torch.tensor([0, 5, 77])
    torch.library.opcheck(torch.ops.smplcore.skin_blocked, (handle, None, feats, transforms))
    torch.library.opcheck(torch.ops.smplcore.skin_blocked, (handle, ids, feats, transforms))
    torch.library.opcheck(torch.ops.smplcore.blend, (handle, None, feats.requires_grad_()))
    torch.library.opcheck(torch.ops.smplcore.skin, (handle, None, rest, transforms.requires_grad_()))
    torch.library.opcheck(torch.ops.smplcore.joint_basis, (handle, feats.detach()))


@pytest.mark.parametrize("model_type", ["mano", "smpl"])
def test_a_compiled_joints_only_call_is_exact(fake_models, model_type):
    """MANO's joints need no vertex: no mesh is built; SMPL's extra joints are read from the mesh."""
    model = _model(fake_models, model_type)
    params = _inputs(model, 2)
    with torch.no_grad():
        expected_ops = {"smplcore.joint_basis"} | ({"smplcore.skin_blocked"} if model_type == "smpl" else set())
        assert _recorded_ops(model, {**params, "return_verts": False}) == expected_ops
        torch._dynamo.reset()
        compiled = torch.compile(model, fullgraph=True, backend="aot_eager")
        a, b = compiled(**params, return_verts=False), model(**params, return_verts=False)
    assert (a.joints - b.joints).abs().max() < 1e-5


def test_dual_quaternion_skinning_compiles_exactly_through_the_plain_pass(fake_models):
    model = _model(fake_models, "smpl", skinning="dqs")
    params = _inputs(model, 2)
    with torch.no_grad():
        assert not _recorded_ops(model, params)
        torch._dynamo.reset()
        compiled = torch.compile(model, fullgraph=True, backend="aot_eager")
        a, b = compiled(**params), model(**params)
    assert (a.vertices - b.vertices).abs().max() < 1e-5 and (a.joints - b.joints).abs().max() < 1e-5


def test_translated_keypoints_of_a_compiled_forward_match_eager(tmp_path):
    """Regressed keypoints are read from the translated mesh there: their values must not depend on the
    regressor's rows summing to one (here they sum to 0.5)."""
    import numpy as np

    num_verts = smplcore.BodyModel(model_type="open").setup.data.v_template.shape[0]
    rng = np.random.default_rng(0)
    matrix = np.where(rng.random((17, num_verts)) < 0.003, rng.random((17, num_verts)), 0.0)
    np.save(tmp_path / "half.npy", 0.5 * matrix / matrix.sum(axis=1, keepdims=True))
    model = smplcore.create(model_type="open", joint_regressors={"h36m17": tmp_path / "half.npy"})
    params = _inputs(model, 2)
    with torch.no_grad():
        torch._dynamo.reset()
        compiled = torch.compile(model, fullgraph=True, backend="aot_eager")
        a, b = compiled(**params), model(**params)
    assert (a.vertices - b.vertices).abs().max() < 1e-5
    assert (a.joints - b.joints).abs().max() < 1e-5
