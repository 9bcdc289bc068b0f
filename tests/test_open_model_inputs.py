"""What the open model does with what users pass it: SMPL-family betas (a warning, once), its betas count,
a model path it ignores (a warning), and gender spellings."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import smplcore
from smplcore.io.locate import OPEN_MODEL_PATH
from smplcore.io.open_model import open_model_path
from smplcore.motion import ProcessOptions, ShapeSpaceWarning, load_motion, process_tree, sequence
from smplcore.motion.synthetic import write_sequence

pytestmark = pytest.mark.skipif(not OPEN_MODEL_PATH.exists(), reason="the open model is not built")


@pytest.fixture
def fresh_warnings(monkeypatch):
    """Forget which once-per-process warnings were given (other tests may have triggered them)."""
    monkeypatch.setattr(sequence, "_warned_shape_space", set())


@pytest.fixture(scope="module")
def smplh_file(tmp_path_factory):
    return write_sequence(tmp_path_factory.mktemp("motion") / "in" / "walk_poses.npz", frames=12, fps=30.0)


def test_smpl_family_betas_fed_to_the_open_model_warn_once(smplh_file, fresh_warnings):
    motion = load_motion(smplh_file)
    assert motion.model_type == "smplh" and np.any(motion.betas)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        motion.model_params("open")
        motion.model_params("open")  # once per process
        motion.model_params("smplh")  # its own model: nothing to say
    shape_space = [w for w in caught if issubclass(w.category, ShapeSpaceWarning)]
    assert len(shape_space) == 1
    assert Path(shape_space[0].filename).name == "test_open_model_inputs.py"  # the caller's line
    message = str(shape_space[0].message)
    assert "SMPL+H shape coefficients" in message and "open model" in message and "num_betas=0" in message


def test_zero_betas_do_not_warn(smplh_file, fresh_warnings):
    from dataclasses import replace

    motion = replace(load_motion(smplh_file), betas=np.zeros(16))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeSpaceWarning)
        motion.model_params("open")


def test_process_on_the_open_model_warns_once_in_the_calling_process(smplh_file, tmp_path, fresh_warnings):
    second = write_sequence(smplh_file.parent / "run_poses.npz", frames=8, fps=30.0, seed=3)
    with pytest.warns(ShapeSpaceWarning, match="SMPL\\+H shape coefficients") as caught:
        summary = process_tree(smplh_file.parent, tmp_path / "out", ProcessOptions(), workers=0, progress=False)
    assert summary.done == 2 and summary.open_model_betas == ["smplh"]
    assert len([w for w in caught if issubclass(w.category, ShapeSpaceWarning)]) == 1
    assert Path(caught[0].filename).name == "test_open_model_inputs.py"
    manifest = (tmp_path / "out" / "manifest.json").read_text()
    assert "open_model_betas" not in manifest
    second.unlink()


def test_process_without_betas_does_not_warn(smplh_file, tmp_path, fresh_warnings):
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeSpaceWarning)
        summary = process_tree(smplh_file, tmp_path / "out", ProcessOptions(num_betas=0), workers=0, progress=False)
    assert summary.done == 1 and summary.open_model_betas == []


def test_export_on_the_open_model_says_so(smplh_file, tmp_path, capsys, fresh_warnings):
    pytest.importorskip("trimesh")
    from smplcore.cli import main

    assert main(["export", str(smplh_file), "-o", str(tmp_path / "body.obj")]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: betas: the motion's betas are SMPL+H shape coefficients") == 1


def test_open_model_takes_ten_betas_by_default_like_smplx_and_all_sixteen_on_request():
    torch = pytest.importorskip("torch")
    data_betas = smplcore.BodyModel(model_type="open").setup.data.num_betas
    assert data_betas == 16
    module, body = smplcore.create(model_type="open"), smplcore.BodyModel(model_type="open")
    assert module.num_betas == body.num_betas == 10 and module.betas.shape == (1, 10)
    full = smplcore.create(model_type="open", num_betas=16)
    assert full.num_betas == 16 and smplcore.BodyModel(model_type="open", num_betas=16).num_betas == 16
    betas = torch.zeros(1, 16)
    betas[0, 12] = 2.0  # a component past the tenth changes the body
    assert (full(betas=betas).vertices - full().vertices).abs().max() > 1e-3
    with pytest.warns(UserWarning, match="num_betas=20 asked, but .* holds 16 shape components; using 16"):
        assert smplcore.create(model_type="open", num_betas=20).num_betas == 16


def test_a_model_folder_given_to_the_open_model_warns(tmp_path):
    pytest.importorskip("torch")
    for make in (smplcore.create, smplcore.BodyModel):
        with pytest.warns(UserWarning, match="model_type='open' is the packaged open model") as caught:
            model = make(tmp_path, model_type="open")
        assert Path(caught[0].filename).name == "test_open_model_inputs.py"
        assert model.setup.data.source == str(open_model_path("neutral"))
    with warnings.catch_warnings():  # the open model's own file, or no path: nothing ignored
        warnings.simplefilter("error")
        smplcore.BodyModel(open_model_path("male"), model_type="open")
        smplcore.create(model_type="open")


@pytest.mark.parametrize("spelling, gender", [("Male", "male"), (" FEMALE", "female"), ("neutral ", "neutral")])
def test_gender_spellings_are_normalised(spelling, gender):
    pytest.importorskip("torch")
    module = smplcore.create(model_type="open", gender=spelling)
    assert module.gender == gender and module.setup.data.source == str(open_model_path(gender))
    assert f"Gender: {gender.upper()}" in repr(module)
    body = smplcore.BodyModel(model_type="open", gender=spelling)
    assert body.setup.data.gender == gender


def test_an_unknown_gender_is_a_clear_error():
    pytest.importorskip("torch")
    for make in (smplcore.create, smplcore.BodyModel):
        with pytest.raises(
            ValueError, match=r"gender: the open model comes as \['female', 'male', 'neutral'\], got 'x'"
        ):
            make(model_type="open", gender="x")
