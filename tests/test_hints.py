"""Error messages that say what to do (issue 31, items 6 and 7): widths of another model, betas beyond
``num_betas``, a motion's model type, genders; what a fit or an export leaves out is named."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import smplcore
from smplcore.errors import ShapeError
from smplcore.motion import Motion


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open")


def test_16_betas_into_a_10_beta_model_mention_num_betas(open_model):
    with pytest.raises(ShapeError, match=r"betas: expected shape \(B, <=10\), got \(1, 16\).*num_betas=16"):
        open_model(betas=np.zeros((1, 16)))
    assert smplcore.BodyModel(model_type="open", num_betas=16)(betas=np.zeros((1, 16))).vertices.shape[0] == 1


def test_16_betas_into_a_torch_model_mention_num_betas():
    torch = pytest.importorskip("torch")
    model = smplcore.create(model_type="open")
    with pytest.raises(ShapeError, match="num_betas=16"):
        model(betas=torch.zeros(1, 16))


def test_63_body_values_into_smpl_say_21_against_23_joints(open_model):
    with pytest.raises(ShapeError, match=r"63 values are 21 body joints.*this model has 23"):
        open_model(body_pose=np.zeros((1, 63)))


def test_69_body_values_into_smplx_say_23_against_21_joints(fake_models):
    model = smplcore.BodyModel(fake_models["smplx_neutral_npz"], model_type="smplx")
    with pytest.raises(ShapeError, match=r"69 values are SMPL's 23 body joints; this model has 21"):
        model(body_pose=np.zeros((1, 69)))


def test_a_72_value_motion_suggests_model_type_smpl():
    with pytest.raises(ShapeError, match=r"72 values per frame are a 'smpl' motion: model_type='smpl'"):
        Motion(poses=np.zeros((3, 72)), trans=np.zeros((3, 3)), betas=np.zeros(10), fps=30.0)


@pytest.mark.parametrize("gender,meant", [("m", "male"), ("F", "female"), ("kid", None)])
def test_an_unknown_gender_lists_the_valid_ones(fake_models, gender, meant):
    folder = fake_models["root"]
    with pytest.raises(ValueError, match=r"gender: expected 'neutral', 'male' or 'female'") as exc:
        smplcore.create(folder, model_type="smpl", gender=gender)
    assert (f"did you mean {meant!r}" in str(exc.value)) == (meant is not None)


def test_body_model_has_its_gender(fake_models):
    assert smplcore.BodyModel(model_type="open").gender == "neutral"
    assert smplcore.BodyModel(model_type="open", gender=" Female").gender == "female"
    assert smplcore.BodyModel(fake_models["root"], model_type="smpl", gender="male").gender == "male"


def test_a_coco_file_names_the_images_without_a_person(tmp_path, capsys):
    from fakes_fit2d import natural_poses, scene
    from smplcore.cli import main

    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    rng = np.random.default_rng(4)
    camera = smplcore.fit.Camera.from_image_size(1000, 1000)
    keypoints, _, _ = scene(model, natural_poses(model, 1, rng), rng, camera=camera)
    person = np.c_[keypoints[0, :, :2], np.full(17, 2)].reshape(-1).tolist()
    doc = {
        "images": [{"id": i, "file_name": f"{i}.jpg", "width": 1000, "height": 1000} for i in (1, 2, 3)],
        "annotations": [{"id": 1, "image_id": 2, "category_id": 1, "num_keypoints": 17, "keypoints": person}],
        "categories": [{"id": 1, "name": "person"}],
    }
    (tmp_path / "people.json").write_text(json.dumps(doc))
    assert main(["fit", str(tmp_path / "people.json"), "-o", str(tmp_path / "people.npz"), "--max-iter", "3"]) == 0
    printed = capsys.readouterr().out
    assert ": 1 body, mean error" in printed and "1 frames" not in printed, printed
    assert "images without a person of 6 or more labelled keypoints (not in the output): 1, 3" in printed, printed


def test_exporting_a_motion_with_dmpls_without_the_dmpl_file_warns(tmp_path, capsys):
    from smplcore.cli import main
    from smplcore.motion import save_motion

    motion = Motion(np.zeros((2, 156)), np.zeros((2, 3)), np.zeros(16), 30.0, dmpls=np.full((2, 8), 0.5))
    path = save_motion(motion, tmp_path / "walk.npz")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["export", str(path), "-o", str(tmp_path / "walk.glb"), "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "dmpls: the input has DMPL soft-tissue coefficients (8 per frame) that are not used; add --dmpl" in err
    assert main(["export", str(path), "-o", str(tmp_path / "walk.bvh"), "--no-progress"]) == 0
    assert "dmpls" not in capsys.readouterr().err  # a BVH holds no mesh: nothing is lost
