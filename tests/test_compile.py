"""``torch.compile(model, fullgraph=True)`` and ``torch.export`` of the forward: exact, with and without
autograd. Inductor (what users run) on SMPL-X, the model with every feature; the graph capture itself
(``aot_eager``, fast) on every other model type."""

from __future__ import annotations

import pytest

import smplcore

torch = pytest.importorskip("torch")


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
