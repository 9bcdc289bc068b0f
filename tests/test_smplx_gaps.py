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
