"""``smplcore demo``: the main job writes a reloadable mesh and a PNG with the bodies in frame."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.cli import main

trimesh = pytest.importorskip("trimesh")
PIL = pytest.importorskip("PIL.Image")


def _render_or_skip(fn):
    try:
        return fn()
    except RuntimeError as exc:
        if "offscreen OpenGL context" in str(exc):
            pytest.skip(f"no offscreen OpenGL here: {exc}")
        raise


def _foreground(png):
    image = np.asarray(PIL.open(png).convert("RGB")).astype(int)
    return np.abs(image - image[0, 0]).sum(axis=2) > 30


def test_demo_on_the_open_model(tmp_path, capsys):
    status = _render_or_skip(lambda: main(["demo", "--out", str(tmp_path)]))
    assert status == 0
    printed = capsys.readouterr().out
    assert str(tmp_path / "body.obj") in printed and str(tmp_path / "body.png") in printed
    mask = _foreground(tmp_path / "body.png")
    assert 0.03 < mask.mean() < 0.6
    rows, cols = np.nonzero(mask)
    assert rows.min() > 0 and cols.min() > 0 and rows.max() < mask.shape[0] - 1 and cols.max() < mask.shape[1] - 1
    # Four bodies side by side: at least four separate runs of foreground columns.
    occupied = mask.any(axis=0).astype(int)
    assert np.count_nonzero(np.diff(occupied) == 1) >= 4
    mesh = trimesh.load(tmp_path / "body.obj", process=False, maintain_order=True)
    model = smplcore.BodyModel(model_type="open")
    assert mesh.vertices.shape == (model.setup.data.num_vertices, 3)
    np.testing.assert_array_equal(mesh.faces, model.faces)


def test_demo_with_a_users_model_pose_file_and_ply(tmp_path, fake_models):
    pose_file = tmp_path / "pose.npy"
    np.save(pose_file, np.zeros((2, 72)))
    out = tmp_path / "out"
    status = _render_or_skip(
        lambda: main(
            [
                "demo",
                "--model-path",
                str(fake_models["smpl_neutral_pkl"]),
                "--pose",
                str(pose_file),
                "--format",
                "ply",
                "--betas",
                "1,-0.5",
                "--out",
                str(out),
            ]
        )
    )
    assert status == 0
    mesh = trimesh.load(out / "body.ply", process=False)
    assert mesh.vertices.shape == (6890, 3)
    assert _foreground(out / "body.png").mean() > 0.01


def test_demo_reports_bad_arguments(tmp_path, capsys):
    assert main(["demo", "--poses", "moonwalk", "--out", str(tmp_path), "--no-render"]) == 2
    assert "unknown ['moonwalk']" in capsys.readouterr().err


def test_demo_textures_the_open_model(tmp_path, capsys):
    """Default: the UV grid on the bodies and with the OBJ; --texture FILE draws that image; 'none' none."""
    red = tmp_path / "red.png"
    PIL.fromarray(np.tile(np.array([200, 20, 20], np.uint8), (32, 32, 1))).save(red)
    out = tmp_path / "red"
    assert _render_or_skip(lambda: main(["demo", "--out", str(out), "--texture", str(red), "--poses", "t-pose"])) == 0
    assert f"texture: {out / 'body_texture.png'}" in capsys.readouterr().out
    image = np.asarray(PIL.open(out / "body.png").convert("RGB")).astype(int)
    body = _foreground(out / "body.png")
    assert (image[body, 0] > image[body, 2] + 40).mean() > 0.8  # the body is red: the texture is drawn
    text = (out / "body.obj").read_text()
    assert text.startswith("# written by smplcore\nmtllib body.mtl\n") and "\nvt " in text
    written = np.asarray(PIL.open(out / "body_texture.png").convert("RGB"))
    np.testing.assert_array_equal(written, np.asarray(PIL.open(red)))
    # the default is the UV grid: many colours on the body
    grid = tmp_path / "grid"
    assert main(["demo", "--out", str(grid), "--poses", "t-pose"]) == 0
    pixels = np.asarray(PIL.open(grid / "body.png").convert("RGB"))[_foreground(grid / "body.png")]
    assert len(np.unique(pixels // 32, axis=0)) > 20
    plain = tmp_path / "plain"
    assert main(["demo", "--out", str(plain), "--texture", "none", "--no-render"]) == 0
    assert not (plain / "body_texture.png").exists() and "\nvt " in (plain / "body.obj").read_text()
