"""The engine's math: exact rotations with correct gradients, NumPy == torch, float64 end to end."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from smplcore.engine import KinematicTree, rodrigues, world_transforms

torch = pytest.importorskip("torch")


def test_rodrigues_matches_scipy_over_all_angles():
    rng = np.random.default_rng(0)
    axes = rng.normal(size=(400, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate(
        [[0.0, 1e-12, 1e-7, 1e-4, 1e-3, 0.5, np.pi - 1e-6, np.pi, 2.5 * np.pi], rng.uniform(0, 2 * np.pi, 391)]
    )
    rotvec = axes * angles[:, None]
    np.testing.assert_allclose(rodrigues(rotvec), Rotation.from_rotvec(rotvec).as_matrix(), atol=1e-14)


def test_rodrigues_is_exactly_identity_at_zero():
    assert np.array_equal(rodrigues(np.zeros((2, 3))), np.broadcast_to(np.eye(3), (2, 3, 3)))


@pytest.mark.parametrize("point", ["zero", "tiny", "pi", "random"])
def test_rodrigues_gradients_are_finite_and_correct(point):
    rotvec = (
        {
            "zero": torch.zeros(1, 3),
            "tiny": torch.full((1, 3), 1e-5),
            "pi": torch.tensor([[0.0, np.pi, 0.0]]),
            "random": torch.tensor([[0.3, -1.2, 0.7]]),
        }[point]
        .double()
        .requires_grad_(True)
    )
    assert torch.autograd.gradcheck(rodrigues, (rotvec,), eps=1e-6, atol=1e-8)
    rodrigues(rotvec).sum().backward()
    assert torch.isfinite(rotvec.grad).all()


def test_rodrigues_gradient_at_zero_is_the_skew_generator():
    """dR/dr at r = 0 is the cross-product matrix: d R[2,1] / d r_x = 1, d R[1,2] / d r_x = -1."""
    rotvec = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    jac = torch.autograd.functional.jacobian(rodrigues, rotvec)  # (3, 3, 3)
    assert jac[2, 1, 0] == 1 and jac[1, 2, 0] == -1 and jac[0, 2, 1] == 1 and jac[0, 0, 0] == 0


def test_world_transforms_compose_along_the_chain():
    parents = [-1, 0, 1, 1, 3]
    tree = KinematicTree.from_parents(parents)
    rng = np.random.default_rng(1)
    rot = Rotation.from_rotvec(rng.normal(size=(5, 3))).as_matrix()[None]
    joints = rng.normal(size=(1, 5, 3))
    world_rot, world_pos = world_transforms(rot, joints, tree)
    expected_rot, expected_pos = [rot[0, 0]], [joints[0, 0]]
    for j in range(1, 5):
        p = parents[j]
        expected_rot.append(expected_rot[p] @ rot[0, j])
        expected_pos.append(expected_rot[p] @ (joints[0, j] - joints[0, p]) + expected_pos[p])
    np.testing.assert_allclose(world_rot[0], np.stack(expected_rot), atol=1e-12)
    np.testing.assert_allclose(world_pos[0], np.stack(expected_pos), atol=1e-12)


def test_kinematic_tree_rejects_children_before_parents():
    with pytest.raises(ValueError, match="parents must come before"):
        KinematicTree.from_parents([-1, 2, 0])


@pytest.mark.parametrize(
    "key,model_type,options",
    [
        ("smpl_neutral_pkl", "smpl", {}),
        ("smplh_neutral_pkl", "smplh", {"use_pca": True, "num_pca_comps": 12}),
        ("smplx_neutral_npz", "smplx", {"use_face_contour": True, "num_expression_coeffs": 20}),
        ("mano_left_pkl", "mano", {"use_pca": False}),
        ("flame_neutral_pkl", "flame", {"use_face_contour": True}),
    ],
)
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_numpy_front_end_equals_torch_front_end(fake_models, key, model_type, options, dtype):
    import smplcore

    np_model = smplcore.BodyModel(fake_models[key], dtype=np.dtype(dtype), **options)
    t_model = smplcore.create(fake_models[key], dtype=getattr(torch, dtype), **options)
    rng = np.random.default_rng(2)
    params = {"betas": rng.normal(size=(3, np_model.num_betas)), "transl": rng.normal(size=(3, 3))}
    if np_model.num_expression_coeffs:
        params["expression"] = rng.normal(size=(3, np_model.num_expression_coeffs))
    for block in np_model.pose_blocks:
        params[block] = rng.normal(0, 0.4, size=(3, np_model.setup.pose_width(block)))
    a = np_model(**params)
    with torch.no_grad():
        b = t_model(**{k: torch.as_tensor(v) for k, v in params.items()})
    tol = 1e-5 if dtype == "float32" else 1e-12
    assert a.vertices.dtype == np.dtype(dtype) and b.vertices.dtype == getattr(torch, dtype)
    np.testing.assert_allclose(a.vertices, b.vertices.numpy(), atol=tol)
    np.testing.assert_allclose(a.joints, b.joints.numpy(), atol=tol)
    assert a.joints.shape[1] == len(np_model.joint_names)


def test_float64_matches_a_float64_reference(fake_models):
    """float64 all the way: our float32 and float64 agree to float32 precision, and float64 to smplx in float64."""
    import warnings

    import smplx

    import smplcore

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = smplx.create(str(fake_models["root"]), model_type="smpl", dtype=torch.float64)
    ours = smplcore.create(fake_models["root"], model_type="smpl", dtype=torch.float64)
    rng = np.random.default_rng(4)
    params = {
        "betas": torch.tensor(rng.normal(size=(2, 10))),
        "body_pose": torch.tensor(rng.normal(0, 0.5, (2, 69))),
        "global_orient": torch.tensor(rng.normal(0, 0.5, (2, 3))),
    }
    with torch.no_grad():
        diff = (ours(**params).vertices - ref(**params).vertices).abs().max().item()
    assert ours.v_template.dtype == torch.float64
    assert diff < 1e-7  # smplx's epsilon-added norm in Rodrigues limits agreement to ~1e-8


def test_gradcheck_through_the_whole_model_in_float64(fake_models):
    import smplcore

    model = smplcore.create(fake_models["mano_right_pkl"], dtype=torch.float64, use_pca=False)

    def f(betas, pose):
        return model(betas=betas, global_orient=pose[:, :3], hand_pose=pose[:, 3:]).joints

    betas = torch.randn(1, 10, dtype=torch.float64, requires_grad=True)
    half_turns = torch.full((1, 48), np.pi / np.sqrt(3.0), dtype=torch.float64)  # |θ| = π per joint
    for pose in (torch.zeros(1, 48, dtype=torch.float64), half_turns):
        pose = pose.clone().requires_grad_(True)
        assert torch.autograd.gradcheck(f, (betas, pose), eps=1e-6, atol=1e-6)


def _random_params(model, batch: int, seed: int, grad: bool = False) -> dict:
    gen = torch.Generator().manual_seed(seed)
    params = {
        "betas": torch.randn(batch, model.num_betas, generator=gen),
        "transl": torch.randn(batch, 3, generator=gen),
    }
    if model.SPEC.has_expression:
        params["expression"] = torch.randn(batch, model.num_expression_coeffs, generator=gen)
    for block in model.SPEC.pose_blocks:
        params[block.name] = 0.4 * torch.randn(batch, model.setup.pose_width(block.name), generator=gen)
    return {k: v.requires_grad_(grad) for k, v in params.items()}


@pytest.mark.parametrize(
    "key,model_type,options",
    [
        ("smpl_neutral_pkl", "smpl", {}),
        ("smplh_neutral_pkl", "smplh", {"use_pca": False}),
        ("smplx_neutral_npz", "smplx", {"use_face_contour": True}),
        ("mano_right_pkl", "mano", {"use_pca": False}),
        ("flame_neutral_pkl", "flame", {}),
    ],
)
@pytest.mark.parametrize("batch", [8, 70])  # the skeleton in NumPy (small batch) and in torch
def test_vertex_blocked_inference_equals_the_plain_pass(fake_models, monkeypatch, key, model_type, options, batch):
    """The no-grad path (mesh cut into vertex blocks, joints per block) equals the autograd path."""
    import smplcore
    from smplcore.engine import backend
    from smplcore.engine.kernels import blocked

    assert (batch <= backend.SMALL_BATCH) == (batch == 8)
    monkeypatch.setattr(blocked, "_PLANE_VALUES", batch * 100)  # blocks of 100 vertices
    monkeypatch.setattr(blocked, "_MIN_BLOCK", 1)
    monkeypatch.setattr(blocked, "_APPLY_VALUES", 3 * 100)  # skinned 3 bodies at a time
    model = smplcore.create(fake_models[key], **options)
    num_verts = model.v_template.shape[0]
    sizes = [b.stop - b.start for b in model.source.fast_arrays().vertex_blocks(blocked.block_size(batch, num_verts))]
    assert len(sizes) > 5 and sum(sizes) == num_verts
    params = _random_params(model, batch, seed=3)
    with torch.no_grad():
        fast = model(**params)
    params["betas"].requires_grad_(True)  # autograd records: the plain pass
    plain = model(**params)
    assert (fast.vertices - plain.vertices).abs().max() < 1e-5
    assert (fast.joints - plain.joints).abs().max() < 1e-5

    np_model = smplcore.BodyModel(fake_models[key], **options)
    out = np_model(**{k: v.detach().numpy() for k, v in params.items()})
    np.testing.assert_allclose(out.vertices, plain.vertices.detach().numpy(), atol=1e-5)


def test_vertex_blocks_hold_exactly_the_nonzero_weights():
    from smplcore.engine.kernels.blocked import vertex_blocks

    rng = np.random.default_rng(0)
    weights_t = np.where(rng.random((7, 50)) < 0.2, rng.random((7, 50)), 0.0)
    weights_t[:, 40:] = rng.random((7, 10))  # the last block uses every joint
    blocks = vertex_blocks(weights_t, 10)
    assert [(b.start, b.stop) for b in blocks] == [(s, s + 10) for s in range(0, 50, 10)]
    for b in blocks:
        dense = np.zeros((7, b.stop - b.start))
        joints = np.arange(7) if b.joints is None else b.joints
        dense[joints] = b.weights_t
        np.testing.assert_array_equal(dense, weights_t[:, b.start : b.stop])
    assert blocks[-1].joints is None and all(len(b.joints) < 7 for b in blocks[:-1] if b.joints is not None)


def test_skinning_autograd_node_passes_gradcheck(monkeypatch):
    from smplcore.engine.kernels import skin_autograd
    from smplcore.engine.kernels.blocked import vertex_blocks
    from smplcore.engine.skeleton import skin

    monkeypatch.setattr(skin_autograd, "_CHUNK_VALUES", 8)  # 2 bodies per chunk over blocks of 4 vertices
    gen = torch.Generator().manual_seed(5)
    rest = torch.randn(3, 3, 11, dtype=torch.float64, generator=gen, requires_grad=True)
    transforms = torch.randn(3, 4, 12, dtype=torch.float64, generator=gen, requires_grad=True)
    weights_t = torch.rand(4, 11, dtype=torch.float64, generator=gen)
    weights_t[:2, :4] = 0  # the first block uses joints 2 and 3 only
    blocks = vertex_blocks(weights_t, 4)
    assert blocks[0].joints.tolist() == [2, 3]
    assert torch.autograd.gradcheck(lambda r, t: skin_autograd.skin_with_gradients(r, t, blocks), (rest, transforms))
    # and it is the same function as the op-by-op formula
    reference = skin(rest, transforms, weights_t)
    assert torch.allclose(skin_autograd.skin_with_gradients(rest, transforms, blocks), reference, atol=1e-12)


def _onednn_or_skip():
    from smplcore.engine.kernels import gemm

    if not gemm.available(torch.zeros(1)):
        pytest.skip("this torch build has no oneDNN: nothing is packed")


@pytest.mark.parametrize(
    "key,options",
    [
        ("smpl_neutral_pkl", {}),
        ("smplx_neutral_npz", {"use_face_contour": True, "use_pca": False}),
    ],
)
@pytest.mark.parametrize("batch", [1, 9, 600])  # whole mesh (NumPy skeleton), whole mesh, vertex blocks
def test_packed_products_equal_plain_products(fake_models, monkeypatch, key, options, batch):
    """oneDNN-packed bases and weights (float32 CPU) give the results and gradients of torch.mm."""
    import smplcore

    _onednn_or_skip()
    packed, plain = smplcore.create(fake_models[key], **options), smplcore.create(fake_models[key], **options)
    params = _random_params(packed, batch, seed=8)
    with torch.no_grad():
        b = packed(**params)  # packs its arrays (once, on first use)
        monkeypatch.setenv("SMPLCORE_ONEDNN", "0")
        a = plain(**params)
        monkeypatch.delenv("SMPLCORE_ONEDNN")
    assert (a.vertices - b.vertices).abs().max() < 1e-5 and (a.joints - b.joints).abs().max() < 1e-5
    from smplcore.engine.kernels import blocked

    arrays = packed.source.fast_arrays()
    size = blocked.block_size(batch, arrays.weights_t.shape[1])
    assert all(blk.packed_blend is None for blk in plain.source.fast_arrays().vertex_blocks(size))
    blocks = arrays.vertex_blocks(size)
    assert all(blk.packed_blend is not None and blk.packed_weights is not None for blk in blocks)
    assert (len(blocks) > 1) == (batch == 600)

    if batch == 600:
        return
    grads = []
    for model, env in ((plain, "0"), (packed, "1")):
        monkeypatch.setenv("SMPLCORE_ONEDNN", env)
        params = _random_params(model, batch, seed=9, grad=True)
        out = model(**params)
        ((out.vertices**2).sum() + out.joints.sum()).backward()
        grads.append({k: v.grad for k, v in params.items()})
    assert arrays.packed_blend() is not None
    for k in grads[0]:
        scale = grads[0][k].abs().max().item() + 1
        assert (grads[0][k] - grads[1][k]).abs().max().item() < 1e-4 * scale, k


def test_packed_product_backward_is_the_transposed_product():
    from smplcore.engine.kernels import gemm

    _onednn_or_skip()
    gen = torch.Generator().manual_seed(1)
    a = torch.randn(5, 40, generator=gen, requires_grad=True)
    matrix = torch.randn(40, 300, generator=gen)
    out = gemm.product_with_gradients(a, gemm.pack(matrix), gemm.pack(matrix.T))
    grad = torch.randn(5, 300, generator=gen)
    out.backward(grad)
    assert torch.allclose(out, a @ matrix, atol=1e-4)
    assert torch.allclose(a.grad, grad @ matrix.T, atol=1e-4)
    assert gemm.pack(matrix.double()) is None and gemm.pack(matrix.numpy()) is None  # float32 torch only
