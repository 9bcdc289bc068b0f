"""``smplcore export`` to USD / USDZ, ``.smpl`` and the Blender add-on npz (``--format`` or the output suffix)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import smplcore
from export_helpers import make_motion, without_correctives
from smplcore.cli import main
from smplcore.export.smplfile import load_blender_npz, read_smpl
from smplcore.motion import save_motion

pytest.importorskip("pxr", reason="the export extra (usd-core) is not installed")

pytestmark = pytest.mark.filterwarnings("ignore:.*pose-corrective.*:UserWarning")


@pytest.fixture(scope="module")
def smplx_motion(tmp_path_factory):
    path = tmp_path_factory.mktemp("motion") / "talk.npz"
    motion = make_motion("smplx", seconds=0.5, fps=30.0, seed=12)
    save_motion(motion, path)
    return path, motion


def test_usdz_from_a_motion_and_smpl_back_again(tmp_path, capsys, fake_models, smplx_motion):
    from test_export_usd import baked_points, forward, validation_errors

    path, motion = smplx_motion
    model_path = str(fake_models["smplx_neutral_npz"])
    out = tmp_path / "talk.usdz"
    args = ["export", str(path), "-o", str(out), "--model-path", model_path, "--pose-correctives", "--unit-weights"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "morph targets: 972 (pose_0_pos, pose_0_neg" in printed  # 2 x 9 x 54
    assert f"wrote {out} (usdz" in printed and "15 frame(s) at 30 fps, 55 joints" in printed
    assert validation_errors(out) == []
    model = smplcore.BodyModel(model_path, use_pca=False, flat_hand_mean=True)
    points = baked_points(out, [3, 11])
    for k, got in points.items():
        assert float(np.abs(got - forward(model, motion, k)).max()) < 1e-4

    smpl_out = tmp_path / "talk.smpl"
    assert main(["export", str(path), "-o", str(smpl_out)]) == 0  # a motion needs no model
    assert "(smpl, " in capsys.readouterr().out
    np.testing.assert_allclose(read_smpl(smpl_out).full_pose(), motion.poses, atol=1e-6)
    usd_out = tmp_path / "again.usdc"
    assert main(["export", str(smpl_out), "-o", str(usd_out), "--model-path", model_path, "--frames", "2:6"]) == 0
    assert "4 frame(s) at 30 fps" in capsys.readouterr().out


def test_usd_with_format_and_texture_on_the_open_model(tmp_path, capsys, smplx_motion):
    pytest.importorskip("PIL")
    path, _ = smplx_motion
    out = tmp_path / "o.usda"
    assert (
        main(["export", str(path), "-o", str(out), "--format", "usd", "--texture", "uv-grid", "--num-betas", "0"]) == 0
    )
    assert (tmp_path / "textures" / "body_albedo.png").is_file()
    assert "primvars:st" in out.read_text()
    assert main(["export", str(path), "-o", str(tmp_path / "o.usd"), "--format", "usdz"]) == 2
    assert "--format usdz writes .usdz files" in capsys.readouterr().err
    assert main(["export", str(path), "-o", str(tmp_path / "o.smpl"), "--texture", "uv-grid"]) == 2
    assert "a smpl file holds no texture" in capsys.readouterr().err


def test_fit_result_to_smpl_and_blender_npz(tmp_path, capsys, fake_models):
    """A parameter set (what a fit writes) goes through the model: PCA hands become absolute axis-angle."""
    rng = np.random.default_rng(3)
    params = {
        "betas": rng.normal(size=10).tolist(),
        "global_orient": rng.normal(0, 0.3, 3).tolist(),
        "body_pose": rng.normal(0, 0.3, 63).tolist(),
        "left_hand_pose": rng.normal(0, 0.5, 12).tolist(),
        "right_hand_pose": rng.normal(0, 0.5, 12).tolist(),
        "transl": [0.1, 0.2, 0.3],
    }
    (tmp_path / "fit.json").write_text(json.dumps(params))
    model_path = str(fake_models["smplx_neutral_npz"])
    out = tmp_path / "fit.smpl"
    assert main(["export", str(tmp_path / "fit.json"), "-o", str(out), "--model-path", model_path]) == 0
    assert "1 frame(s)" in capsys.readouterr().out
    pca = smplcore.BodyModel(model_path, use_pca=True, num_pca_comps=12, flat_hand_mean=False)
    flat = smplcore.BodyModel(model_path, use_pca=False, flat_hand_mean=True)
    expected = pca(**{k: np.asarray(v)[None] for k, v in params.items()}).vertices
    got = flat(**read_smpl(out).to_motion().model_params("smplx")).vertices
    assert float(np.abs(got - expected).max()) < 1e-4

    npz = tmp_path / "blender.npz"
    args = ["export", str(tmp_path / "fit.json"), "-o", str(npz), "--format", "blender-npz", "--model-path", model_path]
    assert main([*args, "--up", "z"]) == 0
    assert "anim_format AMASS" in capsys.readouterr().out
    back = load_blender_npz(npz, up="z", model=flat)
    assert float(np.abs(flat(**back.model_params("smplx")).vertices - expected).max()) < 1e-4


def test_a_npz_output_needs_the_format(tmp_path, capsys, smplx_motion):
    path, _ = smplx_motion
    assert main(["export", str(path), "-o", str(tmp_path / "x.npz")]) == 2
    assert "unsupported suffix '.npz'" in capsys.readouterr().err


def test_usd_without_correctives_reports_them(tmp_path, capsys, fake_models):
    from test_export_usd import forward, skinned_points

    motion = make_motion("smpl", seconds=0.2, seed=13)
    save_motion(motion, tmp_path / "m.npz")
    out = tmp_path / "m.usd"
    assert (
        main(["export", str(tmp_path / "m.npz"), "-o", str(out), "--model-path", str(fake_models["smpl_neutral_npz"])])
        == 0
    )
    printed = capsys.readouterr()
    assert "pose correctives not exported" in printed.out
    model = smplcore.BodyModel(fake_models["smpl_neutral_npz"])
    plain = without_correctives(model)
    got = skinned_points(out, [4])[4]
    assert float(np.abs(got - forward(plain, motion, 4)).max()) < 1e-4


def test_format_joins_another_exporters_format_option():
    """Another exporter may own ``--format`` (the suffix formats): the interchange formats become more of its
    choices instead of a second option."""
    import argparse

    from smplcore.export.cli_usd import add_arguments, format_of

    parser = argparse.ArgumentParser()
    parser.add_argument("-o", "--output")
    parser.add_argument("--format", choices=["glb", "fbx"], default=None, help="output format")
    parser.add_argument("--pose-correctives", action="store_true", help=".fbx: pose correctives")
    add_arguments(parser)
    assert [a.dest for a in parser._actions].count("format") == 1
    assert [a.dest for a in parser._actions].count("pose_correctives") == 1
    assert parser.parse_args(["-o", "x.usd", "--pose-correctives"]).pose_correctives
    args = parser.parse_args(["-o", "body", "--format", "usdz"])
    assert format_of(args) == "usdz" and str(args.output) == "body.usdz"  # OUT without a suffix gets it
    assert format_of(parser.parse_args(["-o", "x.glb", "--format", "glb"])) is None
    assert format_of(parser.parse_args(["-o", "x.usda"])) == "usd"


def test_a_fit_result_exports_to_usd_and_smpl(tmp_path, fake_models):
    """``smplcore.fit``'s result object (its ``params``, torch tensors or arrays, one row per fitted body) is an
    export source: each fitted body a frame."""
    torch = pytest.importorskip("torch")
    from smplcore.export import save_smpl, save_usd
    from smplcore.fit.result import FitResult
    from test_export_usd import skinned_points

    model = smplcore.BodyModel(fake_models["smpl_neutral_npz"])
    rng = np.random.default_rng(4)
    params = {
        "betas": torch.tensor(rng.normal(size=(3, 10))),
        "global_orient": torch.tensor(rng.normal(0, 0.3, (3, 3))),
        "body_pose": torch.tensor(rng.normal(0, 0.3, (3, 69))),
        "transl": torch.tensor(rng.normal(0, 0.3, (3, 3))),
    }
    arrays = {k: v.numpy() for k, v in params.items()}
    arrays["betas"] = np.repeat(arrays["betas"][:1], 3, axis=0)  # one body shape: the first fit's
    fit = FitResult(params={**params, "betas": torch.tensor(arrays["betas"])})
    report = save_usd(tmp_path / "fit.usdc", model, fit, fps=10)
    assert report.num_frames == 3 and report.fps == 10
    plain = without_correctives(model)
    for k, got in skinned_points(tmp_path / "fit.usdc", [0, 2]).items():
        expected = plain(**{n: v[k : k + 1] for n, v in arrays.items()}).vertices[0]
        assert float(np.abs(got - expected).max()) < 1e-4
    save_smpl(tmp_path / "fit.smpl", fit, model, fps=10)
    data = read_smpl(tmp_path / "fit.smpl")
    assert (data.frame_count, data.fps, data.model_type) == (3, 10.0, "smpl")
    expected = model(**arrays).vertices
    assert float(np.abs(model(**data.to_motion().model_params("smpl")).vertices - expected).max()) < 1e-4
