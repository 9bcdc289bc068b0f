"""``smplcore export``: every output format from motions and parameter sets, on fakes and the open model."""

from __future__ import annotations

import json

import numpy as np
import pytest

import smplcore
from export_helpers import GlbReader, make_motion, open_model, validate, without_correctives
from smplcore.cli import main
from smplcore.motion import save_motion

trimesh = pytest.importorskip("trimesh", reason="the export extra (trimesh) is not installed")
pytest.importorskip("pygltflib", reason="the export extra (pygltflib) is not installed")

pytestmark = pytest.mark.filterwarnings("ignore:.*pose-corrective.*:UserWarning")


@pytest.fixture(scope="module")
def smplh_motion(tmp_path_factory):
    """An AMASS-style SMPL+H motion file (156 pose values, 16 betas, mocap_framerate)."""
    path = tmp_path_factory.mktemp("motion") / "walk.npz"
    motion = make_motion("smplh", seconds=2.0, fps=30.0, num_betas=16)
    save_motion(motion, path)
    return path, motion


def _smplh(fake_models):
    return smplcore.BodyModel(fake_models["smplh_female_npz"], use_pca=False, flat_hand_mean=True, num_betas=16)


def test_glb_from_amass_motion(tmp_path, capsys, fake_models, smplh_motion):
    path, motion = smplh_motion
    out = tmp_path / "walk.glb"
    assert main(["export", str(path), "-o", str(out), "--model-path", str(fake_models["smplh_female_npz"])]) == 0
    printed = capsys.readouterr()
    assert f"wrote {out}" in printed.out and "60 frame(s) at 30 fps" in printed.out
    assert "top 4 of up to" in printed.out and "pose correctives not exported" in printed.out
    assert validate(out)["issues"]["numErrors"] == 0
    model = _smplh(fake_models)
    reader = GlbReader(out)
    params = motion.model_params("smplh", model.skeleton_joint_names)
    expected = without_correctives(model)(**{k: v[40:41] if k != "betas" else v for k, v in params.items()})
    np.testing.assert_allclose(reader.skinned_vertices(40), expected.vertices[0], atol=1e-5)


def test_bvh_and_frame_selection(tmp_path, capsys, fake_models, smplh_motion):
    path, _ = smplh_motion
    out = tmp_path / "walk.bvh"
    assert (
        main(
            [
                "export",
                str(path),
                "-o",
                str(out),
                "--model-path",
                str(fake_models["smplh_female_npz"]),
                "--frames",
                "10:50:2",
                "--bvh-scale",
                "100",
                "--no-progress",
            ]
        )
        == 0
    )
    assert "20 frame(s) at 15 fps" in capsys.readouterr().out
    text = out.read_text()
    assert "Frames: 20\n" in text and "Frame Time: 0.06666667\n" in text
    assert "ROOT pelvis" in text and text.count("End Site") == 3 + 10  # head, feet, fingertips


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_mesh_frame_keeps_vertex_order(tmp_path, capsys, fake_models, smplh_motion, suffix):
    path, motion = smplh_motion
    out = tmp_path / f"frame{suffix}"
    assert (
        main(
            [
                "export",
                str(path),
                "-o",
                str(out),
                "--model-path",
                str(fake_models["smplh_female_npz"]),
                "--frame",
                "7",
                "--colors",
                "weights",
            ]
        )
        == 0
    )
    assert "frame 7 of 60" in capsys.readouterr().out
    model = _smplh(fake_models)
    params = motion.model_params("smplh", model.skeleton_joint_names)
    expected = model(**{k: v[7:8] if k != "betas" else v for k, v in params.items()})  # with pose correctives
    mesh = trimesh.load(out, process=False)
    np.testing.assert_allclose(mesh.vertices, expected.vertices[0], atol=1e-6)
    np.testing.assert_array_equal(mesh.faces, model.faces)
    assert mesh.visual.vertex_colors.shape == (len(mesh.vertices), 4)


def test_parameter_set_files(tmp_path, capsys, fake_models):
    rng = np.random.default_rng(0)
    params = {
        "betas": rng.normal(size=10).tolist(),
        "body_pose": rng.normal(0, 0.3, 69).tolist(),
        "transl": [0.0, 0.0, 1.0],
    }
    (tmp_path / "p.json").write_text(json.dumps(params))
    np.savez(tmp_path / "p.npz", **{k: np.asarray(v) for k, v in params.items()})
    model_path = str(fake_models["smpl_neutral_npz"])
    for name in ("p.json", "p.npz"):
        out = tmp_path / f"{name}.glb"
        assert main(["export", str(tmp_path / name), "-o", str(out), "--model-path", model_path]) == 0
        assert "1 frame(s) at 30 fps" in capsys.readouterr().out
        assert out.stat().st_size > 0
    assert validate(tmp_path / "p.json.glb")["issues"]["numErrors"] == 0
    ply = tmp_path / "p.ply"
    assert main(["export", str(tmp_path / "p.npz"), "-o", str(ply), "--model-path", model_path]) == 0
    model = smplcore.BodyModel(model_path)
    expected = model(**{k: np.asarray(v)[None] for k, v in params.items()})
    np.testing.assert_allclose(trimesh.load(ply, process=False).vertices, expected.vertices[0], atol=1e-6)


def test_default_is_the_open_model(tmp_path, capsys, smplh_motion):
    model = open_model()  # skips while the open model is not built
    path, _ = smplh_motion
    for suffix in (".glb", ".bvh", ".obj"):
        out = tmp_path / f"o{suffix}"
        assert main(["export", str(path), "-o", str(out)]) == 0
        assert out.stat().st_size > 0
    printed = capsys.readouterr().out
    # the open model has a UV map: the glb's mesh is split along its seams (more vertices than the model)
    from smplcore.export.uv import model_uv, split_seams

    written = split_seams(model.faces, *model_uv(model)).num_vertices
    assert written > model.skinning_weights.shape[0]
    assert f"24 joints, {written} vertices" in printed
    assert validate(tmp_path / "o.glb")["issues"]["numErrors"] == 0
    assert "\nvt " in (tmp_path / "o.obj").read_text()


def test_texture_option(tmp_path, capsys, smplh_motion, fake_models):
    open_model()
    path, _ = smplh_motion
    assert main(["export", str(path), "-o", str(tmp_path / "t.glb"), "--texture", "uv-grid", "--frames", "0:3"]) == 0
    result = validate(tmp_path / "t.glb")
    assert result["issues"]["numErrors"] == 0 and result["info"]["hasTextures"]
    assert main(["export", str(path), "-o", str(tmp_path / "t.obj"), "--texture", "uv-grid"]) == 0
    assert (tmp_path / "t_texture.png").is_file() and "map_Kd t_texture.png" in (tmp_path / "t.mtl").read_text()
    capsys.readouterr()
    assert main(["export", str(path), "-o", str(tmp_path / "t.bvh"), "--texture", "uv-grid"]) == 2
    assert "--texture: textures are written to .obj, .glb and .fbx" in capsys.readouterr().err
    smpl = str(fake_models["smpl_neutral_npz"])
    assert main(["export", str(path), "-o", str(tmp_path / "s.obj"), "--model-path", smpl, "--texture", "uv-grid"]) == 2
    assert "--texture: the smpl model has no UV map" in capsys.readouterr().err


def test_errors_exit_with_status_2(tmp_path, capsys, smplh_motion):
    path, _ = smplh_motion
    assert main(["export", str(path), "-o", str(tmp_path / "x.abc")]) == 2
    assert "unsupported suffix" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing.npz"), "-o", str(tmp_path / "x.glb")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["export", str(path), "-o", str(tmp_path / "x.obj"), "--frame", "999"]) == 2
    assert "--frame" in capsys.readouterr().err


def test_the_open_model_is_exported_in_the_motion_gender(tmp_path):
    """The open model has three genders: a male motion is exported with the male mesh (and --gender wins)."""
    import dataclasses

    motion = dataclasses.replace(make_motion("smpl", seconds=0.2, fps=30.0), gender="male")
    path = save_motion(motion, tmp_path / "him.npz")
    for gender, flag in (("male", []), ("female", ["--gender", "female"])):
        out = tmp_path / f"{gender}.obj"
        assert main(["export", str(path), "-o", str(out), "--frame", "0", *flag]) == 0
        model = smplcore.BodyModel(model_type="open", gender=gender)
        params = motion.model_params("open", model.skeleton_joint_names)
        expected = model(**{k: v[:1] if k != "betas" else v for k, v in params.items()}).vertices[0]
        written = np.array([line.split()[1:4] for line in out.read_text().splitlines() if line.startswith("v ")], float)
        assert written.shape == expected.shape and np.abs(written - expected).max() < 1e-4
