"""The command line's first contact: ``--version``, ``convert``, frame ranges past the end, and a missing
optional dependency as one line naming the extra (exit 2, no traceback), for every command that needs one."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from smplcore.cli import main
from smplcore.io import load_model
from smplcore.io.locate import OPEN_MODEL_PATH
from smplcore.motion.synthetic import write_sequence

needs_open = pytest.mark.skipif(not OPEN_MODEL_PATH.exists(), reason="the open model is not built")


def _missing(monkeypatch, *modules: str) -> None:
    """Make ``import m`` fail for each module (and its submodules), as when it is not installed."""
    for name in list(sys.modules):
        if name.split(".")[0] in modules:
            monkeypatch.delitem(sys.modules, name)
    for name in modules:
        monkeypatch.setitem(sys.modules, name, None)


def _one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err.strip()


def test_version(capsys):
    from smplcore import __version__

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"smplcore {__version__}"


def test_convert_creates_the_output_folder(fake_models, tmp_path, capsys):
    src = fake_models["smpl_male_pkl"]
    nested = tmp_path / "a" / "b" / "male.npz"
    assert main(["convert", str(src), str(nested)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {nested}"
    folder = tmp_path / "new" / "models"
    assert main(["convert", str(src), f"{folder}/"]) == 0  # a folder: the input's name, as .npz
    written = folder / "SMPL_MALE.npz"
    assert capsys.readouterr().out.strip() == f"wrote {written}"
    ours, official = load_model(written), load_model(src)
    assert (ours.model_type, ours.gender) == ("smpl", "male")
    np.testing.assert_array_equal(ours.v_template, official.v_template)
    with np.load(written, allow_pickle=False) as z:  # pickle-free
        assert "v_template" in z


def test_convert_help_describes_its_arguments(capsys):
    with pytest.raises(SystemExit):
        main(["convert", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "IN the model file to read (.pkl or .npz)" in text
    assert "OUT the .npz to write, or a folder (created if missing)" in text
    assert "--model-type MODEL_TYPE smpl, smplh, smplx, mano or flame" in text
    assert "smplx cannot read it" in text


@needs_open
def test_export_frames_past_the_end_says_how_many_frames(tmp_path, capsys):
    motion = write_sequence(tmp_path / "walk.npz", 300, 30.0, "smplh", "male")
    assert main(["export", str(motion), "-o", str(tmp_path / "w.glb"), "--frames", "500:600"]) == 2
    err = _one_line(capsys)
    assert err == (
        f"smplcore export: error: --frames: 500:600 selects no frame; the motion {motion} has 300 frame(s) (0:300)"
    )
    assert not (tmp_path / "w.glb").exists()
    assert main(["export", str(motion), "-o", str(tmp_path / "w.bvh"), "--frames", "290:600", "--no-progress"]) == 0
    assert ": 10 frame(s) at 30 fps" in capsys.readouterr().out


# ---------------------------------------------------------------------------------------------------
# missing optional dependencies


@needs_open
def test_demo_without_its_extra(monkeypatch, tmp_path, capsys):
    _missing(monkeypatch, "pyrender")
    assert main(["demo", "--out", str(tmp_path / "d")]) == 2
    err = _one_line(capsys)
    assert err.startswith("smplcore demo: rendering needs pyrender (") and err.endswith('pip install "smplcore[demo]"')
    _missing(monkeypatch, "trimesh")
    assert main(["demo", "--out", str(tmp_path / "d"), "--no-render", "--format", "ply"]) == 2
    assert _one_line(capsys).startswith("smplcore demo: save_mesh needs trimesh (")
    _missing(monkeypatch, "PIL")
    assert main(["demo", "--out", str(tmp_path / "d"), "--no-render"]) == 2
    err = _one_line(capsys)
    assert "needs Pillow" in err and err.endswith('pip install "smplcore[demo]"')


@needs_open
def test_export_without_its_extra(monkeypatch, tmp_path, capsys):
    motion = write_sequence(tmp_path / "walk.npz", 10, 30.0, "smplh", "male")
    _missing(monkeypatch, "pygltflib", "trimesh")
    assert main(["export", str(motion), "-o", str(tmp_path / "w.glb"), "--no-progress"]) == 2
    err = _one_line(capsys)
    assert err.startswith("smplcore export: save_glb needs pygltflib (")
    assert err.endswith('install it with: pip install "smplcore[export]"')
    assert main(["export", str(motion), "-o", str(tmp_path / "w.ply")]) == 2
    assert _one_line(capsys).endswith('pip install "smplcore[export]"')
    assert main(["export", str(motion), "-o", str(tmp_path / "w.bvh"), "--no-progress"]) == 0  # BVH needs neither


@needs_open
def test_process_without_torch_or_ray(monkeypatch, tmp_path, capsys):
    import smplcore.motion.models as models

    write_sequence(tmp_path / "in" / "a_poses.npz", 10, 30.0, "smplh", "male")
    argv = ["process", str(tmp_path / "in"), str(tmp_path / "out"), "--workers", "0", "--quiet"]
    monkeypatch.setattr(models, "torch_available", lambda: False)
    assert main([*argv, "--backend", "torch"]) == 2
    err = _one_line(capsys)
    assert "PyTorch is not installed; install it with: pip install torch==2.13.0, or use --backend numpy" in err
    assert not (tmp_path / "out").exists()  # refused before anything started
    _missing(monkeypatch, "ray")
    assert main([*argv, "--ray"]) == 2
    assert _one_line(capsys).endswith(
        '--ray needs Ray, which is not installed; install it with: pip install "smplcore[ray]"'
    )


@needs_open
def test_render_without_pyrender_stops_before_writing(monkeypatch, tmp_path, capsys):
    pytest.importorskip("imageio_ffmpeg")
    motion = write_sequence(tmp_path / "walk.npz", 10, 30.0, "smplh", "male")
    _missing(monkeypatch, "pyrender")
    assert main(["render", str(motion), "-o", str(tmp_path / "w.mp4"), "--no-progress"]) == 2
    err = _one_line(capsys)
    assert err == (
        "smplcore render: writing videos needs pyrender, which is not installed; "
        'install it with: pip install "smplcore[view]"'
    )
    assert not (tmp_path / "w.mp4").exists()


def test_an_unexpected_missing_module_still_shows_its_traceback(monkeypatch):
    """Only optional dependencies become one line: a module smplcore does not list is a bug to show."""
    from smplcore import cli

    def run(args):
        raise ModuleNotFoundError("No module named 'not_a_dependency'", name="not_a_dependency")

    monkeypatch.setattr(cli, "_cmd_convert", run)
    with pytest.raises(ModuleNotFoundError, match="not_a_dependency"):
        main(["convert", "a.pkl", "b.npz"])


def test_a_plain_import_error_of_an_optional_module_is_one_line_too(monkeypatch, capsys):
    """Code that imports an optional module directly (no ``require``) still ends in one line and exit 2."""
    from smplcore import cli

    def run(args):
        raise ModuleNotFoundError("No module named 'trimesh'", name="trimesh")

    monkeypatch.setattr(cli, "_cmd_convert", run)
    assert main(["convert", "a.pkl", "b.npz"]) == 2
    assert _one_line(capsys) == (
        "smplcore convert: this command needs trimesh (No module named 'trimesh'); "
        'install it with: pip install "smplcore[export]"'
    )


@needs_open
def test_create_without_torch_says_what_to_install():
    code = textwrap.dedent(
        """
        import sys
        sys.modules["torch"] = None  # as if torch were not installed
        import smplcore
        model = smplcore.BodyModel(model_type="open")  # the NumPy front end needs no torch
        try:
            smplcore.create(model_type="open")
        except ImportError as exc:
            print(type(exc).__name__, isinstance(exc, RuntimeError))
            print(exc)
        """
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    kind, message = done.stdout.splitlines()
    assert kind == "MissingDependencyError True"
    assert message.startswith("smplcore.create is the PyTorch front end and needs torch, which is not installed")
    assert "pip install torch==2.13.0" in message and "smplcore.BodyModel" in message


def test_export_use_pca_decides_how_hand_poses_are_read(fake_models, tmp_path, capsys):
    """A parameter set's 45-value hand poses are axis-angle by default and with --no-use-pca; --use-pca
    reads them as PCA coefficients, which the model (6 components) refuses with a fix-it message."""
    import trimesh

    rng = np.random.default_rng(0)
    params = tmp_path / "params.npz"
    np.savez(
        params,
        betas=np.zeros((1, 10)),
        body_pose=rng.normal(0, 0.2, (1, 63)),
        left_hand_pose=rng.normal(0, 0.3, (1, 45)),
        right_hand_pose=rng.normal(0, 0.3, (1, 45)),
    )
    base = ["export", str(params), "--model-path", str(fake_models["root"]), "--model-type", "smplh"]
    assert main([*base, "-o", str(tmp_path / "a.ply")]) == 0
    assert main([*base, "-o", str(tmp_path / "b.ply"), "--no-use-pca", "--ext", "pkl"]) == 0
    a = trimesh.load(tmp_path / "a.ply", process=False).vertices
    b = trimesh.load(tmp_path / "b.ply", process=False).vertices
    np.testing.assert_array_equal(a, b)
    capsys.readouterr()
    assert main([*base, "-o", str(tmp_path / "c.ply"), "--use-pca"]) == 2
    err = _one_line(capsys)
    assert "left_hand_pose: expected shape (B, 6), got (1, 45)" in err and "use_pca=False for 45 axis-angle" in err
