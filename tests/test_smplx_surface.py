"""smplcore's torch modules present smplx 0.1.28's whole public surface, compared with smplx itself on the
same fake files: class tree, constants, attributes, parameters (and their order), buffers, ``state_dict``
(loadable both ways with ``strict=True``), which output fields are filled, and in-place buffer edits."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

torch = pytest.importorskip("torch")
smplx = pytest.importorskip("smplx")

import smplcore  # noqa: E402
from smplx_surface import class_tree, filled_fields, surface  # noqa: E402

CASES = [
    ("smpl", {}),
    ("smpl", {"gender": "male", "batch_size": 3, "create_transl": False}),
    ("smplh", {}),
    ("smplh", {"use_pca": False, "flat_hand_mean": True}),
    ("smplx", {}),
    ("smplx", {"use_face_contour": True, "use_pca": False, "num_expression_coeffs": 5}),
    ("mano", {}),
    ("mano", {"is_rhand": False, "num_pca_comps": 12}),
    (
        "mano",
        {
            "create_global_orient": False,
            "create_hand_pose": False,
            "create_betas": False,
            "create_transl": False,
            "create_body_pose": False,
        },
    ),
    ("flame", {}),
    ("flame", {"use_face_contour": True}),
]


def _pair(root, model_type, options, factory):
    if factory == "build_layer":  # smplx's Layers set the create_* flags themselves
        options = {k: v for k, v in options.items() if not k.startswith("create_")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = getattr(smplx, factory)(str(root), model_type=model_type, **options)
        ours = getattr(smplcore, factory)(root, model_type=model_type, **options)
    return ref, ours


@pytest.mark.parametrize("factory", ["create", "build_layer"])
@pytest.mark.parametrize("model_type,options", CASES)
def test_public_surface_matches_smplx(fake_models, model_type, options, factory):
    ref, ours = _pair(fake_models["root"], model_type, options, factory)
    assert class_tree(type(ours)) == class_tree(type(ref))
    assert surface(ours) == surface(ref)
    if not any(True for _ in ref.parameters()) and factory == "create":
        return  # smplx's forward needs its parameters (AttributeError); ours runs, as the other tests show
    with torch.no_grad():
        assert filled_fields(ours()) == filled_fields(ref())
        batch = 3 if options.get("batch_size") == 3 else 1
        assert filled_fields(ours(transl=torch.ones(batch, 3))) == filled_fields(ref(transl=torch.ones(batch, 3)))


@pytest.mark.parametrize("model_type,options", [c for c in CASES if c[0] != "mano" or "create_betas" not in c[1]])
def test_state_dicts_load_both_ways_strictly(fake_models, model_type, options):
    ref, ours = _pair(fake_models["root"], model_type, options, "create")
    gen = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for _, p in ref.named_parameters():
            p.copy_(0.3 * torch.randn(p.shape, generator=gen))
        ref.shapedirs.mul_(1.5)  # a changed buffer must travel too
    ours.load_state_dict(ref.state_dict(), strict=True)
    with torch.no_grad():
        a, b = ref(), ours()
    assert (a.vertices - b.vertices).abs().max() < 1e-5 and (a.joints - b.joints).abs().max() < 1e-5
    ref2, _ = _pair(fake_models["root"], model_type, options, "create")
    ref2.load_state_dict(ours.state_dict(), strict=True)
    with torch.no_grad():
        assert (ref2().vertices - b.vertices).abs().max() < 1e-5


def test_isinstance_and_inherited_constants_as_in_smplx(fake_models):
    root = fake_models["root"]
    x = smplcore.create(root, model_type="smplx")
    assert isinstance(x, smplcore.SMPLH) and isinstance(x, smplcore.SMPL)
    assert isinstance(smplcore.build_layer(root, model_type="smplx"), smplcore.SMPLX)
    assert smplcore.FLAME.NUM_BODY_JOINTS == smplx.FLAME.NUM_BODY_JOINTS == 23
    assert issubclass(smplcore.MANOLayer, smplcore.MANO) and issubclass(smplcore.MANO, smplcore.SMPL)


@pytest.mark.parametrize(
    "model_type,edit",
    [
        ("mano", lambda m: m.shapedirs[:, 0, :].mul_(-1)),  # the MANO left-hand fix, done by hand
        ("smplx", lambda m: m.v_template.add_(torch.tensor([0.0, 0.17, 0.0]))),
        ("smplx", lambda m: m.shapedirs.mul_(2.0)),
        ("smpl", lambda m: m.posedirs.mul_(3.0)),
        ("smplh", lambda m: m.left_hand_components.mul_(-1)),
        ("smpl", lambda m: m.J_regressor.copy_(torch.roll(m.J_regressor, 1, dims=1))),
    ],
)
def test_in_place_buffer_edits_reach_the_output_as_in_smplx(fake_models, model_type, edit):
    ref, ours = _pair(fake_models["root"], model_type, {"is_rhand": False} if model_type == "mano" else {}, "create")
    gen = torch.Generator().manual_seed(1)
    params = {"betas": torch.randn(2, 10, generator=gen), "transl": torch.randn(2, 3, generator=gen)}
    if ours.SPEC.has_expression:
        params["expression"] = torch.randn(2, 10, generator=gen)
    for block in ours.SPEC.pose_blocks:
        params[block.name] = 0.4 * torch.randn(2, ours.setup.pose_width(block.name), generator=gen)
    with torch.no_grad():
        before = ours(**params)  # a first forward builds the engine's derived arrays
        edit(ref), edit(ours)
        a, b = ref(**params), ours(**params)
    assert (b.vertices - before.vertices).abs().max() > 1e-3  # the edit changed something
    assert (a.vertices - b.vertices).abs().max() < 1e-5 and (a.joints - b.joints).abs().max() < 1e-5


def test_to_float64_rebuilds_the_engine_arrays(fake_models):
    model = smplcore.create(fake_models["root"], model_type="smpl")
    with torch.no_grad():
        out32 = model(body_pose=torch.full((1, 69), 0.1))
        out64 = model.double()(body_pose=torch.full((1, 69), 0.1, dtype=torch.float64))
    assert out64.vertices.dtype == torch.float64
    assert (out64.vertices.float() - out32.vertices).abs().max() < 1e-5


def test_smplx_folder_without_ext_loads_the_npz(fake_models, tmp_path):
    (tmp_path / "smplx").mkdir()
    src = fake_models["smplx_neutral_npz"]
    (tmp_path / "smplx" / "SMPLX_NEUTRAL.npz").symlink_to(src)
    model = smplcore.create(tmp_path, model_type="smplx")
    assert model.setup.data.source.endswith("SMPLX_NEUTRAL.npz")
    assert smplcore.BodyModel(tmp_path, model_type="smplx").setup.data.source.endswith(".npz")


def test_the_other_format_is_used_when_only_it_is_there(fake_models, tmp_path):
    (tmp_path / "smpl").mkdir()
    (tmp_path / "smpl" / "SMPL_NEUTRAL.pkl").symlink_to(fake_models["smpl_neutral_pkl"])
    # smplx's own demo passes --ext npz for SMPL, which smplx ignores (it always reads .pkl)
    model = smplcore.create(tmp_path, model_type="smpl", ext="npz")
    assert model.setup.data.source.endswith("SMPL_NEUTRAL.pkl")


def test_gender_is_the_keyword_as_in_smplx(fake_models):
    root = fake_models["root"]
    male_file = next(p for p in root.rglob("SMPL_MALE.pkl"))
    assert smplcore.SMPL(male_file).gender == smplx.SMPL(str(male_file)).gender == "neutral"
    assert smplcore.create(root, model_type="mano", is_rhand=False).gender == "neutral"
    assert smplcore.create(root, model_type="smpl", gender="female").gender == "female"


def test_smplx_config_keywords_are_silent_and_typos_get_one_hint(fake_models):
    config = {
        "use_face_contour": True,
        "num_expression_coeffs": 10,
        "use_pca": False,
        "flat_hand_mean": True,
        "create_jaw_pose": True,
        "num_pca_comps": 12,
        "is_rhand": True,
        "use_compressed": False,
        "kid_template_path": "",
        "age": "adult",
        "neck_pose": None,
        "create_neck_pose": True,
    }
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        smplcore.create(fake_models["root"], model_type="smpl", **config)
    assert [str(w.message) for w in caught] == []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        smplcore.create(fake_models["root"], model_type="smpl", num_beta=10, colour="red")
        smplcore.create(fake_models["root"], model_type="smpl", num_beta=10)
    messages = sorted(str(w.message) for w in caught)
    assert len(messages) == 2
    assert "'colour'" in messages[0] and "did you mean" not in messages[0]
    assert "'num_beta'" in messages[1] and "did you mean 'num_betas'?" in messages[1]


def test_output_values_match_smplx_for_layers_with_transl(fake_models):
    ref, ours = _pair(fake_models["root"], "smplx", {}, "build_layer")
    eye = torch.eye(3).expand(2, 21, 3, 3)
    with torch.no_grad():
        a = ref(body_pose=eye, transl=torch.ones(2, 3), betas=torch.ones(2, 10))
        b = ours(body_pose=eye, transl=torch.ones(2, 3), betas=torch.ones(2, 10))
    np.testing.assert_allclose(b.transl.numpy(), a.transl.numpy())
    assert (a.vertices - b.vertices).abs().max() < 1e-5
