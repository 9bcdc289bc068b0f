"""Export inputs go through the motion package's one AMASS reader, with one rule for a missing frame
rate (refused unless the caller gives one; never a guessed 30 fps), and the exporters' skinning is the
engine's."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import smplcore
from oracle import oracle
from smplcore.cli import main
from smplcore.errors import ModelFileError
from smplcore.export.animation import lbs, load_input, prepare_animation
from smplcore.export.skin_metrics import pose_corrective_error
from smplcore.motion import Motion, load_motion, motion_from_arrays
from smplcore.motion.synthetic import random_arrays

# AMASS arrays carry 16 betas; the models here take 10 (the export warns that it drops 6)
pytestmark = pytest.mark.filterwarnings("ignore:betas.*dropping:UserWarning")


def _without_rate(frames: int = 4) -> dict[str, np.ndarray]:
    arrays = random_arrays(frames, fps=50.0, model_type="smplh", gender="neutral", seed=1)
    del arrays["mocap_framerate"]
    return arrays


def _open_model() -> smplcore.BodyModel:
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def test_export_reads_motion_arrays_as_the_motion_reader_does():
    arrays = random_arrays(6, fps=60.0, model_type="smplx", gender="female", seed=2)
    anim_source = prepare_animation(_open_model(), arrays)
    expected = motion_from_arrays(arrays)
    assert anim_source.fps == expected.fps == 60.0
    assert anim_source.num_frames == expected.num_frames == 6
    np.testing.assert_array_equal(anim_source.transl, expected.trans)


def test_a_motion_without_frame_rate_is_refused_with_the_fix():
    with pytest.raises(ModelFileError, match=r"states no frame rate.*fps=") as info:
        prepare_animation(_open_model(), _without_rate())
    assert info.value.key == "mocap_framerate"


def test_a_given_fps_is_the_rate_of_a_motion_without_one_and_overrides_a_stated_one():
    assert prepare_animation(_open_model(), _without_rate(), fps=24.0).fps == 24.0
    stated = random_arrays(4, fps=50.0, model_type="smplh", gender="neutral", seed=1)
    assert prepare_animation(_open_model(), stated).fps == 50.0
    assert prepare_animation(_open_model(), stated, fps=25.0).fps == 25.0


def test_parameter_sets_keep_their_30_fps_default():
    assert prepare_animation(_open_model(), {"body_pose": np.zeros(69)}).fps == 30.0


def test_npz_and_json_motion_files_follow_the_same_rule(tmp_path):
    arrays = _without_rate()
    npz = tmp_path / "walk.npz"
    np.savez(npz, **arrays)
    js = tmp_path / "walk.json"
    js.write_text(json.dumps({k: np.asarray(v).tolist() for k, v in arrays.items()}))
    for path in (npz, js):
        with pytest.raises(ModelFileError, match="states no frame rate"):
            load_input(path)
        motion = load_input(path, fps=20.0)
        assert isinstance(motion, Motion) and motion.fps == 20.0
    # the npz is read by load_motion itself: the same Motion as the motion package gives
    a, b = load_input(npz, fps=20.0), load_motion(npz, default_fps=20.0)
    for field in dataclasses.fields(Motion):
        x, y = getattr(a, field.name), getattr(b, field.name)
        assert np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y


def test_export_cli_takes_the_rate_of_a_motion_without_one_from_fps(tmp_path, capsys):
    npz = tmp_path / "walk.npz"
    np.savez(npz, **_without_rate())
    assert main(["export", str(npz), "-o", str(tmp_path / "a.bvh")]) == 2
    assert "--fps" in capsys.readouterr().err
    assert main(["export", str(npz), "-o", str(tmp_path / "b.bvh"), "--fps", "24", "--no-progress"]) == 0
    assert "Frame Time: 0.04166667" in (tmp_path / "b.bvh").read_text()


def test_single_frame_arrays_without_trans_still_export():
    arrays = {"poses": np.zeros(156), "mocap_framerate": 30.0}
    anim = prepare_animation(_open_model(), arrays)
    assert anim.num_frames == 1 and np.array_equal(anim.transl, np.zeros((1, 3)))


def test_lbs_is_the_engine_skinning_and_matches_the_oracle():
    model = _open_model()
    motion = motion_from_arrays(random_arrays(3, model_type="smplh", gender="neutral", seed=4))
    anim = prepare_animation(model, motion)
    params = motion.model_params("open")
    params["betas"] = np.broadcast_to(anim.betas, (3, anim.betas.shape[0]))
    expected, _ = oracle(model.setup.data, params, num_betas=model.num_betas)
    np.testing.assert_allclose(lbs(anim.rest_vertices, anim.skinning_matrices(), anim.weights), expected, atol=1e-6)


def test_pose_corrective_error_is_what_the_oracle_says_the_correctives_move(fake_models):
    model = smplcore.BodyModel(fake_models["smpl_male_pkl"], dtype=np.float64)
    motion = motion_from_arrays(random_arrays(3, model_type="smplh", gender="male", seed=5))
    anim = prepare_animation(model, motion)
    params = motion.model_params("smpl")
    params["betas"] = np.broadcast_to(anim.betas, (3, anim.betas.shape[0]))
    with_pc, _ = oracle(model.setup.data, params, num_betas=model.num_betas)
    without_pc, _ = oracle(model.setup.data.replace(posedirs=None), params, num_betas=model.num_betas)
    expected = float(np.linalg.norm(with_pc - without_pc, axis=-1).max())
    assert expected > 1e-4
    assert pose_corrective_error(model, anim) == pytest.approx(expected, rel=1e-9, abs=1e-12)
