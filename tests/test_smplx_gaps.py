"""The drop-in gaps of issue 27 (item 8), each compared with smplx 0.1.28 on the same fake files:
the NumPy hand PCA attributes, a callable ``vertex_joint_selector``, ``create_mean_pose``, the kid offset
measured from the file's template under a custom ``v_template``, ``named_buffers()`` order and ``extra_repr``."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

torch = pytest.importorskip("torch")
smplx = pytest.importorskip("smplx")

import smplcore  # noqa: E402

CASES = [
    ("smpl", {}),
    ("smplh", {}),
    ("smplh", {"use_pca": False, "flat_hand_mean": True}),
    ("smplx", {}),
    ("smplx", {"use_face_contour": True, "num_pca_comps": 12}),
    ("mano", {}),
    ("mano", {"is_rhand": False, "use_pca": False}),
    ("flame", {}),
    ("flame", {"use_face_contour": True}),
]


def _pair(root, model_type, options, factory="create"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = getattr(smplx, factory)(str(root), model_type=model_type, **options)
        ours = getattr(smplcore, factory)(root, model_type=model_type, **options)
    return ref, ours


@pytest.mark.parametrize("factory", ["create", "build_layer"])
@pytest.mark.parametrize("model_type,options", CASES)
def test_named_buffers_and_extra_repr_in_smplx_order(fake_models, model_type, options, factory):
    ref, ours = _pair(fake_models["root"], model_type, options, factory)
    assert [k for k, _ in ours.named_buffers()] == [k for k, _ in ref.named_buffers()]
    assert ours.extra_repr() == ref.extra_repr()
    assert repr(ours) == repr(ref)


@pytest.mark.parametrize("model_type,options", CASES + [("smpl", {"use_hands": False})])
def test_the_vertex_joint_selector_has_smplx_tip_names(fake_models, model_type, options):
    ref, ours = _pair(fake_models["root"], model_type, options)
    tips = [getattr(m.vertex_joint_selector, "tip_names", None) for m in (ref, ours)]
    assert tips[1] == tips[0]


@pytest.mark.parametrize("model_type,options", CASES)
def test_numpy_hand_components_as_smplx(fake_models, model_type, options):
    ref, ours = _pair(fake_models["root"], model_type, options)
    for name in ("np_left_hand_components", "np_right_hand_components", "np_hand_components"):
        assert hasattr(ours, name) == hasattr(ref, name), name
        if hasattr(ref, name):
            a, b = getattr(ref, name), getattr(ours, name)
            assert isinstance(b, np.ndarray) and b.shape == a.shape and b.dtype == a.dtype
            np.testing.assert_array_equal(b, a)


@pytest.mark.parametrize("model_type,options", CASES)
def test_create_mean_pose_as_smplx(fake_models, model_type, options):
    ref, ours = _pair(fake_models["root"], model_type, options)
    a, b = ref.create_mean_pose(None), ours.create_mean_pose(None)
    if a is None:
        assert b is None
        return
    assert type(b) is type(a)
    np.testing.assert_allclose(np.asarray(b), np.asarray(a), atol=1e-7)


@pytest.mark.parametrize("model_type", ["smpl", "smplh", "smplx"])
def test_the_vertex_joint_selector_is_callable_as_in_smplx(fake_models, model_type):
    ref, ours = _pair(fake_models["root"], model_type, {})
    gen = torch.Generator().manual_seed(0)
    verts = torch.randn(2, ref.get_num_verts(), 3, generator=gen)
    joints = torch.randn(2, 5, 3, generator=gen)
    expected = ref.vertex_joint_selector(verts, joints)
    torch.testing.assert_close(ours.vertex_joint_selector(verts, joints), expected)
    torch.testing.assert_close(ours.vertex_joint_selector(vertices=verts, joints=joints), expected)


@pytest.mark.parametrize("model_type", ["smpl", "smplx"])
def test_kid_offset_is_measured_from_the_files_template_under_a_custom_v_template(fake_models, model_type):
    root = fake_models["root"]
    kid = str(root / model_type / f"{model_type}_kid_template.npy")
    base = _pair(root, model_type, {})[0].v_template.numpy()
    custom = base * 1.1 + 0.01
    ref, ours = _pair(root, model_type, {"age": "kid", "kid_template_path": kid, "v_template": custom})
    betas = torch.zeros(1, ref.num_betas)  # smplx counts the kid coefficient in num_betas
    for kid_amount in (0.0, 1.0):  # the custom template, then one unit of the kid coefficient
        betas[0, -1] = kid_amount
        with torch.no_grad():
            torch.testing.assert_close(ours(betas=betas).vertices, ref(betas=betas).vertices, atol=1e-5, rtol=0)


# -- a per-sample v_template (B, V, 3) ------------------------------------------------------------------------

TEMPLATE_MODELS = ["smpl", "smplh", "smplx", "mano", "flame"]


def _templates(base: torch.Tensor, n: int) -> torch.Tensor:
    """(n, V, 3) templates: the file's (V, 3) ``base`` scaled and shifted differently per sample."""
    scale = torch.tensor([1.0, 1.1, 0.9, 1.05])[:n, None, None]
    shift = torch.tensor([[0.0, 0.0, 0.0], [0.02, -0.01, 0.03], [-0.03, 0.02, 0.0], [0.0, 0.05, -0.02]])[:n, None]
    return base[None] * scale + shift


def _random_params(ref, batch: int, seed: int = 3) -> dict:
    """Keyword values of batch ``batch`` for each of smplx's parameters of the module ``ref``."""
    gen = torch.Generator().manual_seed(seed)
    out = {}
    for name, p in ref.named_parameters():
        scale = 1.0 if name in ("betas", "expression", "transl") else 0.3
        out[name] = scale * torch.randn(batch, p.shape[1], generator=gen)
    return out


def _close(a, b) -> None:
    torch.testing.assert_close(a.vertices, b.vertices, atol=1e-5, rtol=0)
    torch.testing.assert_close(a.joints, b.joints, atol=1e-5, rtol=0)


@pytest.mark.parametrize("model_type", TEMPLATE_MODELS)
def test_a_per_sample_v_template_is_kept_and_used_per_sample_as_in_smplx(fake_models, model_type):
    root = fake_models["root"]
    base = _pair(root, model_type, {})[0].v_template
    templates = _templates(base, 3)
    ref, ours = _pair(root, model_type, {"v_template": templates, "batch_size": 3})
    assert tuple(ours.v_template.shape) == tuple(ref.v_template.shape) == tuple(templates.shape)
    assert ours.get_num_verts() == base.shape[0]  # smplx's answers the batch size (3) here
    with torch.no_grad():
        _close(ours(), ref())  # the module's parameters (batch 3) with the 3 templates
        params = _random_params(ref, 3)
        _close(ours(**params), ref(**params))
        both = ours(**params)
    # each body is its own template's: the same call with one template per body, one at a time
    for i in range(3):
        single = _pair(root, model_type, {"v_template": templates[i]})[1]
        with torch.no_grad():
            one = single(**{k: v[i : i + 1] for k, v in params.items()})
        torch.testing.assert_close(both.vertices[i : i + 1], one.vertices, atol=1e-5, rtol=0)


@pytest.mark.parametrize("model_type", ["smpl", "smplx"])
def test_a_per_sample_v_template_in_a_layer_as_in_smplx(fake_models, model_type):
    root = fake_models["root"]
    base = _pair(root, model_type, {})[0].v_template
    ref, ours = _pair(root, model_type, {"v_template": _templates(base, 2), "batch_size": 2}, "build_layer")
    gen = torch.Generator().manual_seed(5)
    body = torch.linalg.matrix_exp(_skew(0.3 * torch.randn(2, ref.NUM_BODY_JOINTS, 3, generator=gen)))
    betas = torch.randn(2, 10, generator=gen)
    with torch.no_grad():
        _close(ours(body_pose=body, betas=betas), ref(body_pose=body, betas=betas))


def _skew(v: torch.Tensor) -> torch.Tensor:
    o = torch.zeros_like(v[..., 0])
    x, y, z = v.unbind(-1)
    return torch.stack([o, -z, y, z, o, -x, -y, x, o], -1).reshape(*v.shape[:-1], 3, 3)


@pytest.mark.parametrize("model_type", ["smpl", "smplx", "flame"])
def test_a_v_template_given_to_forward_is_used_for_that_call(fake_models, model_type):
    root = fake_models["root"]
    plain_ref, ours = _pair(root, model_type, {})
    templates = _templates(plain_ref.v_template, 3)
    ref = _pair(root, model_type, {"v_template": templates, "batch_size": 3})[0]
    params = _random_params(ref, 3)
    with torch.no_grad():
        _close(ours(v_template=templates, **params), ref(**params))
        _close(ours(**params), plain_ref(**params))  # the next call has the model's own template again
        one_ref = _pair(root, model_type, {"v_template": templates[1]})[0]
        _close(ours(v_template=templates[1], **params), one_ref(**params))  # (V, 3): every body


def test_a_per_sample_v_template_is_checked(fake_models):
    root = fake_models["root"]
    base = _pair(root, "smpl", {})[0].v_template
    ours = smplcore.create(root, model_type="smpl", v_template=_templates(base, 3), batch_size=3)
    with pytest.raises(smplcore.ShapeError, match="batch size 2 does not match the batch size 3"):
        ours(body_pose=torch.zeros(2, 69))
    with pytest.raises(ValueError, match="v_template.*reference"):
        ours(kernel="blocked")
    with pytest.raises(ValueError, match="rig.*3 templates"):
        _ = ours.rig
    with pytest.raises(smplcore.ShapeError, match=r"v_template: expected shape \(6890, 3\) or \(B, 6890, 3\)"):
        smplcore.create(root, model_type="smpl", v_template=torch.zeros(3, 100, 3))
    with pytest.raises(ValueError, match="v_template: holds NaN"):
        smplcore.create(root, model_type="smpl", v_template=torch.full((2, 6890, 3), float("nan")))
    plain = smplcore.create(root, model_type="smpl")
    with pytest.raises(smplcore.ShapeError, match="v_template"):
        plain(v_template=torch.zeros(6890, 2))
    with pytest.raises(ValueError, match="v_template"):
        plain(v_template=torch.full((6890, 3), float("inf")))
    with pytest.raises(smplcore.ShapeError, match="v_template.*torch"):  # the NumPy model takes one template
        smplcore.BodyModel(root, model_type="smpl", v_template=_templates(base, 2).numpy())


# -- forward's signature and the rest of smplx's public surface ---------------------------------------------


def _positional(fn) -> list[tuple[str, object]]:
    import inspect

    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.POSITIONAL_ONLY)
    return [(p.name, p.default) for p in inspect.signature(fn).parameters.values() if p.kind in kinds]


@pytest.mark.parametrize("factory", ["create", "build_layer"])
@pytest.mark.parametrize("model_type", TEMPLATE_MODELS)
def test_forward_signature_lists_smplx_parameters_in_its_order(fake_models, model_type, factory):
    import inspect

    ref, ours = _pair(fake_models["root"], model_type, {}, factory)
    assert _positional(ours.forward) == _positional(ref.forward)
    params = inspect.signature(ours.forward).parameters
    assert any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())  # as smplx's **kwargs
    for own in ("kernel", "check_finite", "check_rotations", "v_template"):
        assert params[own].kind is inspect.Parameter.KEYWORD_ONLY
    assert inspect.signature(type(ours).forward).parameters["self"].kind is inspect.Parameter.POSITIONAL_OR_KEYWORD


@pytest.mark.parametrize("model_type", ["smpl", "smplh", "smplx", "mano", "flame"])
def test_positional_forward_arguments_as_in_smplx(fake_models, model_type):
    ref, ours = _pair(fake_models["root"], model_type, {})
    params = _random_params(ref, 2)
    names = [n for n, _ in _positional(ref.forward) if n in params]
    args = [params.get(n) for n, _ in _positional(ref.forward)[: len(names) + 1]][: len(names)]
    with torch.no_grad():
        _close(ours(*args), ref(*args))
        a, b = ours(*args, True, True), ref(*args, True, True)  # return_verts, return_full_pose
    torch.testing.assert_close(a.full_pose, b.full_pose, atol=1e-6, rtol=0)
    with pytest.raises(TypeError, match="multiple values for argument 'betas'"):
        ours(params["betas"], betas=params["betas"])
    with pytest.warns(UserWarning, match="did you mean 'global_orient'"):
        ours(global_orientation=params["global_orient"])


@pytest.mark.parametrize("model_type", TEMPLATE_MODELS)
def test_private_counts_smplx_clients_read(fake_models, model_type):
    ref, ours = _pair(fake_models["root"], model_type, {"num_betas": 8})
    for name in ("_num_betas", "_num_expression_coeffs"):
        assert hasattr(ours, name) == hasattr(ref, name), name
        if hasattr(ref, name):
            assert getattr(ours, name) == getattr(ref, name), name


def test_vertex_joint_selector_module_as_in_smplx():
    from smplx.vertex_ids import vertex_ids
    from smplx.vertex_joint_selector import VertexJointSelector as Ref

    from smplcore.smplx_compat.vertex_joint_selector import VertexJointSelector

    for options in ({}, {"use_hands": False}, {"use_feet_keypoints": False, "use_hands": False}):
        ref, ours = Ref(vertex_ids["smplx"], **options), VertexJointSelector(vertex_ids["smplx"], **options)
        torch.testing.assert_close(ours.extra_joints_idxs, ref.extra_joints_idxs)
        assert getattr(ours, "tip_names", None) == getattr(ref, "tip_names", None)
    with pytest.raises(TypeError, match="vertex_ids"):
        VertexJointSelector()


def test_body_models_module_names_as_in_smplx():
    import inspect

    from smplx import body_models as ref

    from smplcore.smplx_compat import body_models as ours

    wanted = [
        n
        for n, v in vars(ref).items()
        if not n.startswith("_")
        and not inspect.ismodule(v)
        and getattr(v, "__module__", "") != "typing"
        and n not in ("Dict", "Optional", "Union")
    ]
    assert [n for n in wanted if not hasattr(ours, n)] == []
