"""Dual-quaternion skinning (``skinning="dqs"``): the reference against first principles, every front end and
kernel against the oracle on vertices and joints, the rest pose against LBS, gradients against finite
differences, the forearm-twist measurement, and ``smplcore process`` / ``smplcore export --skinning dqs``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import smplcore
from oracle import oracle
from smplcore.cli import main
from smplcore.engine import reference
from smplcore.engine.reference import rodrigues

torch = pytest.importorskip("torch")

TOL32, TOL64 = 3e-5, 1e-9

MODELS = [
    ("smpl_neutral_pkl", {}),
    ("smplh_neutral_pkl", {"use_pca": True, "num_pca_comps": 12}),
    ("smplx_neutral_npz", {"use_face_contour": True, "num_expression_coeffs": 10}),
    ("mano_left_pkl", {"use_pca": False}),
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


def _args(fake_models, key, options):
    if key == "open":
        return (None,), {"model_type": "open", **options}
    return (fake_models[key],), dict(options)


def _params(setup, batch, seed, *, scale=0.8, rotmats=False):
    rng = np.random.default_rng(seed)
    params = {"betas": rng.normal(0, 1, (batch, setup.num_betas)), "transl": rng.normal(0, 1, (batch, 3))}
    if setup.spec.has_expression:
        params["expression"] = rng.normal(0, 1, (batch, setup.num_expression_coeffs))
    for block in setup.spec.pose_blocks:
        params[block.name] = rng.normal(0, scale, (batch, setup.pose_width(block.name)))
        if rotmats:
            params[block.name] = rodrigues(rng.normal(0, scale, (batch, block.num_joints, 3)))
    return params


def _expected(setup, params, options, rotation_matrices=False):
    opts = {k: v for k, v in options.items() if k in ORACLE_OPTIONS}
    if rotation_matrices:
        opts["use_pca"] = False
    return oracle(setup.data, params, rotation_matrices=rotation_matrices, skinning="dqs", **opts)


def _check(verts, joints, expected, tol):
    np.testing.assert_allclose(np.asarray(joints, np.float64), expected[1], atol=tol, rtol=0)
    if verts is not None:
        np.testing.assert_allclose(np.asarray(verts, np.float64), expected[0], atol=tol, rtol=0)


# ------------------------------------------------------------------------------------------------
# The reference, from first principles


def test_quaternions_of_rotation_matrices_match_scipy_including_half_turns():
    rotations = Rotation.concatenate(
        [Rotation.random(500, random_state=1), Rotation.from_rotvec(np.pi * np.eye(3)), Rotation.identity(2)]
    )
    q = reference.rotation_quaternions(rotations.as_matrix())
    expected = rotations.as_quat()[:, [3, 0, 1, 2]]  # scipy: (x, y, z, w)
    np.testing.assert_allclose(np.abs((q * expected).sum(axis=-1)), 1.0, atol=1e-12)  # equal up to sign
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)


def test_a_vertex_of_one_joint_moves_rigidly():
    rng = np.random.default_rng(0)
    rot = Rotation.random(6, random_state=2).as_matrix().reshape(2, 3, 3, 3)
    relative = np.zeros((2, 3, 4, 4))
    relative[..., :3, :3], relative[..., :3, 3], relative[..., 3, 3] = rot, rng.normal(size=(2, 3, 3)), 1
    weights = np.eye(3)[[0, 1, 2, 2, 0]]  # 5 vertices, each on one joint
    verts = rng.normal(size=(2, 5, 3))
    got = reference.dual_quaternion_skinning(verts, relative, weights)
    np.testing.assert_allclose(got, reference.linear_blend_skinning(verts, relative, weights), atol=1e-12)


def test_blending_takes_the_short_way_between_antipodal_quaternions():
    # two joints turned by +179° and -179° (= 181°) about z: their quaternions lie in opposite hemispheres;
    # blended half and half in the first one's hemisphere the vertex turns by 180°, not by 0°
    relative = np.tile(np.eye(4), (1, 2, 1, 1))
    relative[0, :, :3, :3] = Rotation.from_rotvec([[0, 0, np.radians(179)], [0, 0, -np.radians(179)]]).as_matrix()
    weights = np.array([[0.5, 0.5], [0.7, 0.3], [0.3, 0.7]])
    verts = np.array([[[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]]])
    got = reference.dual_quaternion_skinning(verts, relative, weights)
    np.testing.assert_allclose(got[0, 0], [-1.0, 0, 0], atol=1e-12)
    # 0.7 of 179° and 0.3 of 181° (whichever joint dominates): about 179.6°, a unit-length result
    for v, angle in ((got[0, 1], 179.6), (got[0, 2], 180.4)):
        np.testing.assert_allclose(np.linalg.norm(v), 1.0, atol=1e-12)
        assert abs(np.degrees(np.arctan2(v[1], v[0])) % 360 - angle) < 0.1
    # either sign of a joint's quaternion is the same transform: the result does not depend on it
    flipped = reference.dual_quaternions(relative[..., :3, :3], relative[..., :3, 3])
    np.testing.assert_allclose(np.abs(flipped[0, :, 3]), np.sin(np.radians(179) / 2), atol=1e-12)


@pytest.mark.parametrize("key", [m[0] for m in MODELS])
def test_rest_pose_equals_lbs(fake_models, key):
    args, kwargs = _args(
        fake_models, key, {"flat_hand_mean": True} if key.startswith(("smplh", "smplx", "mano")) else {}
    )
    betas = np.random.default_rng(3).normal(0, 1, (3, 10))
    dqs = smplcore.BodyModel(*args, dtype=np.float64, skinning="dqs", **kwargs)
    lbs = smplcore.BodyModel(*args, dtype=np.float64, **kwargs)
    params = {"betas": betas[:, : dqs.num_betas], "transl": np.ones((3, 3))}
    shaped = np.stack([dqs.rest_pose(b)[0] for b in params["betas"]]) + 1.0
    # LBS moves a rest vertex by Σ w - 1 times itself: the file's weights sum to 1 within float32 rounding
    slack = 1e-12 + 2 * np.abs(dqs.skinning_weights.sum(axis=1) - 1).max() * np.abs(shaped).max()
    for kernel in ("auto", "reference"):
        dqs.kernel = lbs.kernel = kernel
        a, b = dqs(**params), lbs(**params)
        np.testing.assert_allclose(a.vertices, shaped, atol=1e-12, rtol=0)  # DQS: the rest mesh itself
        np.testing.assert_allclose(a.vertices, b.vertices, atol=slack, rtol=0)
        np.testing.assert_allclose(a.joints, b.joints, atol=slack, rtol=0)
    torch_dqs = smplcore.create(*args, dtype=torch.float64, skinning="dqs", **kwargs)
    out = torch_dqs(**{k: torch.tensor(v) for k, v in params.items()})
    np.testing.assert_allclose(out.vertices.detach().numpy(), shaped, atol=1e-12, rtol=0)


def test_dqs_differs_from_lbs_when_posed(fake_models):
    args, kwargs = _args(fake_models, "smpl_neutral_pkl", {})
    params = _params(smplcore.BodyModel(*args).setup, 2, seed=0)
    a = smplcore.BodyModel(*args, dtype=np.float64, skinning="dqs")(**params).vertices
    b = smplcore.BodyModel(*args, dtype=np.float64)(**params).vertices
    assert np.abs(a - b).max() > 1e-3


# ------------------------------------------------------------------------------------------------
# Front ends and kernels against the oracle


@pytest.mark.parametrize("key,options", MODELS)
@pytest.mark.parametrize("batch", [1, 4])
@pytest.mark.parametrize("kernel", ["auto", "reference"])
def test_numpy_front_end_equals_the_oracle(fake_models, key, options, batch, kernel):
    args, kwargs = _args(fake_models, key, options)
    for dtype, tol in ((np.float64, TOL64), (np.float32, TOL32)):
        model = smplcore.BodyModel(*args, dtype=dtype, kernel=kernel, skinning="dqs", **kwargs)
        params = _params(model.setup, batch, seed=batch)
        expected = _expected(model.setup, params, kwargs)
        out = model(**params)
        _check(out.vertices, out.joints, expected, tol)
        _check(None, model(return_verts=False, **params).joints, expected, tol)


@pytest.mark.parametrize("key,options", MODELS)
@pytest.mark.parametrize("batch", [1, 20])  # one vertex block under autograd up to 16 bodies, then several
@pytest.mark.parametrize("mode", ["inference", "autograd", "reference"])
def test_torch_front_end_equals_the_oracle(fake_models, key, options, batch, mode):
    args, kwargs = _args(fake_models, key, options)
    model = smplcore.create(*args, kernel="reference" if mode == "reference" else "auto", skinning="dqs", **kwargs)
    assert model.skinning == "dqs"
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
    args, kwargs = _args(fake_models, key, options)
    layer = smplcore.build_layer(*args, skinning="dqs", **kwargs)
    params = _params(layer.setup, 3, seed=7, rotmats=True)
    expected = _expected(layer.setup, params, kwargs, rotation_matrices=True)
    with torch.no_grad():
        out = layer(**{k: torch.tensor(v, dtype=torch.float32) for k, v in params.items()})
    _check(out.vertices.numpy(), out.joints.numpy(), expected, TOL32 * 2)


def test_many_vertex_blocks_in_float64_equal_the_oracle(fake_models, monkeypatch):
    from smplcore.engine import body
    from smplcore.engine.kernels import blocked

    monkeypatch.setattr(blocked, "_PLANE_VALUES", 9 * 100)  # blocks of ~100 vertices at B = 9
    monkeypatch.setattr(blocked, "_MIN_BLOCK", 1)
    monkeypatch.setattr(body, "_GRAD_BLOCK", 128)
    monkeypatch.setattr(body, "_GRAD_FEW_BODIES", 2)
    model = smplcore.create(fake_models["smplx_neutral_npz"], dtype=torch.float64, skinning="dqs")
    params = _params(model.setup, 9, seed=3)
    expected = _expected(model.setup, params, {})
    for grad in (False, True):
        out = model(**{k: torch.tensor(v, requires_grad=grad) for k, v in params.items()})
        _check(out.vertices.detach().numpy(), out.joints.detach().numpy(), expected, TOL64)


def test_pairs_whose_sign_flips_are_corrected(fake_models):
    # large rotations put some joints in the other hemisphere than the dominant joint of their vertices (not a
    # parent), which the fast kernel corrects pair by pair: checked to happen here, and to match the oracle
    from smplcore.engine import body
    from smplcore.engine.kernels import dqs

    model = smplcore.BodyModel(fake_models["smplx_neutral_npz"], dtype=np.float64, skinning="dqs", use_pca=False)
    params = _params(model.setup, 6, seed=11, scale=2.0)
    arrays = model.arrays
    rotmats = model(**params).rotmats
    _, transforms = body.pose_skeleton(np.zeros((6, arrays.num_coeffs)), rotmats, arrays.joint_basis, arrays.tree)
    _, _, pairs = arrays.dqs_blocks(arrays.weights_t.shape[1])
    flipped = dqs._prepare(transforms, arrays.tree, pairs)[2]
    assert flipped is not None and flipped.any()
    expected = _expected(model.setup, params, {"use_pca": False})
    out = model(**params)
    _check(out.vertices, out.joints, expected, TOL64)
    tensors = {k: torch.tensor(v, requires_grad=True) for k, v in params.items()}
    out = smplcore.create(fake_models["smplx_neutral_npz"], dtype=torch.float64, skinning="dqs", use_pca=False)(
        **tensors
    )
    _check(out.vertices.detach().numpy(), out.joints.detach().numpy(), expected, TOL64)


def test_fast_dual_quaternions_equal_the_reference_and_follow_their_parents():
    from smplcore.engine.kernels import dqs
    from smplcore.engine.skeleton import KinematicTree

    rotations = Rotation.concatenate(
        [Rotation.random(40, random_state=4), Rotation.from_rotvec(np.pi * np.eye(3)), Rotation.identity(2)]
    )
    rot = rotations.as_matrix()
    t = np.random.default_rng(4).normal(size=(len(rot), 3))
    transforms = np.concatenate([rot.reshape(-1, 9), t], axis=1).reshape(5, 9, 12)
    expected = reference.dual_quaternions(rot, t).reshape(5, 9, 8)
    for x in (transforms, torch.tensor(transforms)):  # the same branch of Shepperd's method: the same sign
        np.testing.assert_allclose(np.asarray(dqs.dual_quaternions(x)), expected, atol=1e-12, rtol=0)
    # in depth order (joints 0, 1, 3, 2, ...): each quaternion in its parent's hemisphere, equal up to sign
    tree = KinematicTree.from_parents([-1, 0, 1, 0, 2, 4, 4, 6, 3])
    order = list(tree.order)
    got = dqs.joint_dual_quaternions(transforms[:, order], tree)
    parent_rows = [order.index(max(tree.parents[j], 0)) for j in order]
    assert ((got[..., :4] * got[:, parent_rows, :4]).sum(axis=-1) >= 0).all()
    sign = np.sign((got[..., :4] * expected[:, order, :4]).sum(axis=-1, keepdims=True))
    np.testing.assert_allclose(got, sign * expected[:, order], atol=1e-12, rtol=0)


@pytest.mark.parametrize("torch_ops", [True, False])  # torch's operations, or NumPy's on the tensors' memory
@pytest.mark.parametrize("batch", [1, 7])
def test_torch_inference_with_either_elementwise_backend_equals_the_oracle(fake_models, monkeypatch, torch_ops, batch):
    from smplcore.engine.kernels import dqs

    monkeypatch.setattr(dqs, "_TORCH_MIN_PLANE", 0 if torch_ops else 1 << 40)
    for key, options in (MODELS[0], MODELS[2], MODELS[5]):
        args, kwargs = _args(fake_models, key, options)
        model = smplcore.create(*args, skinning="dqs", **kwargs)
        params = _params(model.setup, batch, seed=batch + 2)
        expected = _expected(model.setup, params, kwargs)
        with torch.no_grad():
            out = model(**{k: torch.tensor(v, dtype=torch.float32) for k, v in params.items()})
        _check(out.vertices.numpy(), out.joints.numpy(), expected, TOL32 * 2)


def test_body_chunks_with_flipped_pairs_equal_the_oracle(fake_models, monkeypatch):
    # a few bodies per step (their rows gathered per chunk), small vertex blocks, and poses whose corrected
    # pairs occur in some bodies and blocks only; NumPy and torch (both elementwise backends), float64
    from smplcore.engine import body
    from smplcore.engine.kernels import blocked, dqs

    monkeypatch.setattr(blocked, "_PLANE_VALUES", 7 * 512)  # blocks of 512 vertices at B = 7
    monkeypatch.setattr(dqs, "_APPLY_VALUES", (2 * 512, 2 * 512))  # two bodies per step
    path = fake_models["smplx_neutral_npz"]
    model = smplcore.BodyModel(path, dtype=np.float64, skinning="dqs", use_pca=False)
    params = _params(model.setup, 7, seed=12, scale=0.8)
    arrays = model.arrays
    _, transforms = body.pose_skeleton(
        np.zeros((7, arrays.num_coeffs)), model(**params).rotmats, arrays.joint_basis, arrays.tree
    )
    flipped = dqs._prepare(transforms, arrays.tree, arrays.dqs_blocks(512)[2])[2]
    assert flipped is not None and 0 < flipped.any(axis=1).sum() < 7  # some bodies only
    expected = _expected(model.setup, params, {"use_pca": False})
    out = model(**params)
    _check(out.vertices, out.joints, expected, TOL64)
    torch_model = smplcore.create(path, dtype=torch.float64, skinning="dqs", use_pca=False)
    for threshold in (0, 1 << 40):
        monkeypatch.setattr(dqs, "_TORCH_MIN_PLANE", threshold)
        with torch.no_grad():
            out = torch_model(**{k: torch.tensor(v) for k, v in params.items()})
        _check(out.vertices.numpy(), out.joints.numpy(), expected, TOL64)


# ------------------------------------------------------------------------------------------------
# Gradients


@pytest.mark.parametrize("kernel", ["auto", "reference"])
def test_gradients_match_finite_differences(fake_models, kernel):
    model = smplcore.create(fake_models["smpl_neutral_pkl"], dtype=torch.float64, kernel=kernel, skinning="dqs")
    rng = np.random.default_rng(5)
    probe = torch.tensor(rng.normal(size=(2, model.get_num_verts(), 3)))
    start = {k: torch.tensor(v) for k, v in _params(model.setup, 2, seed=6).items()}

    def loss(body_pose, global_orient, betas, transl):
        out = model(body_pose=body_pose, global_orient=global_orient, betas=betas, transl=transl)
        return (out.vertices * probe).sum(dim=(1, 2)), out.joints[:, -5:].sum(dim=(1, 2))

    inputs = tuple(start[k].clone().requires_grad_() for k in ("body_pose", "global_orient", "betas", "transl"))
    assert torch.autograd.gradcheck(loss, inputs, eps=1e-6, atol=1e-6, rtol=1e-5, fast_mode=True)
    zero = tuple(torch.zeros_like(x).requires_grad_() for x in inputs)  # the rest pose: finite, as checked
    assert torch.autograd.gradcheck(loss, zero, eps=1e-6, atol=1e-6, rtol=1e-5, fast_mode=True)


def test_the_fast_and_the_reference_gradients_agree(fake_models):
    grads = {}
    for kernel in ("auto", "reference"):
        model = smplcore.create(fake_models["smplx_neutral_npz"], dtype=torch.float64, kernel=kernel, skinning="dqs")
        params = {k: torch.tensor(v, requires_grad=True) for k, v in _params(model.setup, 3, seed=8).items()}
        out = model(**params)
        ((out.vertices**2).sum() + (out.joints**3).sum()).backward()
        grads[kernel] = {k: v.grad for k, v in params.items()}
    for name, g in grads["auto"].items():
        torch.testing.assert_close(g, grads["reference"][name], atol=1e-8, rtol=1e-7)


# ------------------------------------------------------------------------------------------------
# Options


def test_an_invalid_skinning_is_an_error_naming_it(fake_models):
    for build in (
        lambda: smplcore.create(model_type="open", skinning="dq"),
        lambda: smplcore.BodyModel(model_type="open", skinning="DQS"),
        lambda: smplcore.build_layer(fake_models["smpl_neutral_pkl"], skinning=None),
    ):
        with pytest.raises(ValueError, match=r"skinning: expected 'lbs' .* or 'dqs'"):
            build()
    assert smplcore.create(model_type="open").skinning == "lbs"
    assert smplcore.BodyModel(model_type="open").skinning == "lbs"


# ------------------------------------------------------------------------------------------------
# The measurement: a 150° wrist twist on the open model


def forearm_radius_ratios(skinning: str, degrees: float = 150.0) -> dict[str, float]:
    """Mean distance of forearm vertex rings from the elbow-wrist axis, twisted over rest, for the left wrist
    turned by ``degrees`` about that axis. Rings: vertices at 85-95 % of the forearm's length (the
    forearm near the wrist), and those whose wrist weight is 0.3-0.7 (the blend zone, the worst case)."""
    model = smplcore.BodyModel(model_type="open", dtype=np.float64, skinning=skinning)
    elbow, wrist = (model.skeleton_joint_names.index(n) for n in ("left_elbow", "left_wrist"))
    rest, joints = model.rest_pose()
    axis = joints[wrist] - joints[elbow]
    length = np.linalg.norm(axis)
    axis = axis / length
    pose = np.zeros((1, 3 * (len(joints) - 1)))
    pose[0, 3 * (wrist - 1) : 3 * wrist] = np.radians(degrees) * axis
    posed = model(body_pose=pose).vertices[0]

    def radius(v):
        d = v - joints[elbow]
        return np.linalg.norm(d - (d @ axis)[:, None] * axis, axis=1)

    along = (rest - joints[elbow]) @ axis / length
    w = model.skinning_weights
    rings = {
        "forearm": (along > 0.85) & (along < 0.95) & (radius(rest) < 0.1),
        "blend": (w[:, wrist] >= 0.3) & (w[:, wrist] <= 0.7) & (w[:, elbow] + w[:, wrist] > 0.95),
    }
    return {name: float(radius(posed)[ring].mean() / radius(rest)[ring].mean()) for name, ring in rings.items()}


def test_a_150_degree_wrist_twist_keeps_the_forearm_with_dqs_and_collapses_it_with_lbs():
    lbs, dqs = forearm_radius_ratios("lbs"), forearm_radius_ratios("dqs")
    print(f"forearm radius after a 150° wrist twist: LBS {lbs}, DQS {dqs}")
    assert dqs["forearm"] >= 0.9 and dqs["blend"] >= 0.9
    assert lbs["forearm"] < 0.85 and lbs["blend"] < 0.5  # LBS loses a fifth near the wrist, most in the blend zone


# ------------------------------------------------------------------------------------------------
# smplcore process / export --skinning dqs


@pytest.fixture(scope="module")
def motion_file(tmp_path_factory):
    from smplcore.motion.synthetic import write_sequence

    folder = tmp_path_factory.mktemp("dqs_motion")
    return write_sequence(folder / "walk.npz", frames=12, fps=30.0, model_type="smplh", gender="neutral")


def test_process_with_dqs_writes_dqs_vertices(motion_file, tmp_path):
    from smplcore.motion import load_motion

    out = tmp_path / "out"
    args = [
        "process",
        str(motion_file),
        str(out),
        "--vertices",
        "--extra-joints",
        "--workers",
        "0",
        "--quiet",
        "--num-betas",
        "10",
    ]
    assert main([*args, "--skinning", "dqs"]) == 0
    got = np.load(out / "walk.npz")
    motion = load_motion(motion_file)
    model = smplcore.BodyModel(model_type="open", gender=motion.gender, skinning="dqs")
    params = motion.model_params("open")
    params["betas"] = params["betas"][:, : model.num_betas]
    expected = model(**params)
    np.testing.assert_allclose(got["vertices"], expected.vertices, atol=2e-5)
    np.testing.assert_allclose(got["joints"], expected.joints, atol=2e-5)
    lbs = smplcore.BodyModel(model_type="open", gender=motion.gender)(**params).vertices
    assert np.abs(got["vertices"] - lbs).max() > 1e-3
    # another skinning in the same output folder is a change of settings: refused without --overwrite
    assert main([*args, "--skinning", "lbs"]) != 0


def test_export_ply_with_dqs_writes_dqs_vertices_and_a_glb_says_its_rig_is_lbs(motion_file, tmp_path, capsys):
    trimesh = pytest.importorskip("trimesh")
    from smplcore.motion import load_motion

    obj = tmp_path / "frame5.ply"  # (no UV seams: one vertex per model vertex)
    assert main(["export", str(motion_file), "-o", str(obj), "--frame", "5", "--skinning", "dqs"]) == 0
    mesh = trimesh.load(obj, process=False)
    motion = load_motion(motion_file)
    model = smplcore.BodyModel(model_type="open", skinning="dqs", num_betas=16, flat_hand_mean=True, use_pca=False)
    params = motion.model_params("open", model.skeleton_joint_names)
    expected = model(**{k: v[5:6] if k != "betas" else v for k, v in params.items()}).vertices[0]
    np.testing.assert_allclose(np.asarray(mesh.vertices), expected, atol=1e-5)
    pytest.importorskip("pygltflib")
    capsys.readouterr()
    assert main(["export", str(motion_file), "-o", str(tmp_path / "walk.glb"), "--skinning", "dqs"]) == 0
    assert "glTF skins are linear blend skinning" in capsys.readouterr().err
