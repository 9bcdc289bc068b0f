""".smpl (smplcodec) files and the SMPL-X Blender add-on npz: round trips through Meshcapade's ``smplcodec`` itself
(our write -> their read, their write -> our read), AMASS <-> .smpl, and the add-on's Z-up layout checked on the
model's vertices."""

from __future__ import annotations

import dataclasses
import zipfile

import numpy as np
import pytest

import smplcore
from export_helpers import make_motion
from smplcore.errors import ModelFileError
from smplcore.export.smplfile import (
    Y_TO_Z_UP,
    SmplFile,
    amass_to_smpl,
    load_blender_npz,
    read_smpl,
    save_blender_npz,
    save_smpl,
    smpl_to_amass,
    write_smpl,
)
from smplcore.motion import load_motion, save_motion

F32 = dict(rtol=0, atol=1e-6)


def _codec():
    return pytest.importorskip("smplcodec", reason="smplcodec (test-only dependency) is not installed")


def _motion(model_type: str, **options):
    expression = 10 if model_type == "smplx" else 0
    return make_motion(model_type, seconds=0.3, seed=2, expression=expression, **options)


@pytest.mark.parametrize("model_type", ["smpl", "smplh", "smplx"])
def test_our_write_is_read_by_smplcodec(tmp_path, model_type):
    smplcodec = _codec()
    motion = _motion(model_type)
    path = write_smpl(tmp_path / "a.smpl", SmplFile.from_motion(motion))
    theirs = smplcodec.SMPLCodec.from_file(str(path))
    assert theirs.smpl_version == smplcodec.SMPLVersion.from_string(model_type)
    assert theirs.gender == smplcodec.SMPLGender.NEUTRAL
    assert theirs.frame_count == motion.num_frames and theirs.frame_rate == motion.fps
    np.testing.assert_allclose(theirs.full_pose.reshape(motion.num_frames, -1), motion.poses, **F32)
    np.testing.assert_allclose(theirs.body_translation, motion.trans, **F32)
    np.testing.assert_allclose(theirs.shape_parameters, motion.betas, **F32)
    if model_type == "smplx":
        np.testing.assert_allclose(theirs.expression_parameters, motion.expression, **F32)
    else:
        assert theirs.expression_parameters is None
    with zipfile.ZipFile(path) as z, np.load(path, allow_pickle=False) as npz:  # flat, int32/float32 only
        assert all("/" not in n for n in z.namelist())
        assert {npz[k].dtype for k in npz.files} <= {np.dtype(np.int32), np.dtype(np.float32)}
        assert npz["codecVersion"].dtype == np.int32 and npz["bodyPose"].dtype == np.float32


@pytest.mark.parametrize("model_type", ["smpl", "smplh", "smplx"])
def test_smplcodec_write_is_read_by_us(tmp_path, model_type):
    smplcodec = _codec()
    rng = np.random.default_rng(0)
    frames = 7
    sizes = smplcodec.SMPLParamStructure[smplcodec.SMPLVersion.from_string(model_type)]
    blocks = {
        f.name: rng.normal(size=(frames, *getattr(sizes, f.name))).astype(np.float32)
        for f in dataclasses.fields(sizes)
        if getattr(sizes, f.name) is not None
    }
    theirs = smplcodec.SMPLCodec(
        smpl_version=smplcodec.SMPLVersion.from_string(model_type),
        gender=smplcodec.SMPLGender.FEMALE,
        shape_parameters=rng.normal(size=16).astype(np.float32),
        frame_count=frames,
        frame_rate=60.0,
        body_translation=rng.normal(size=(frames, 3)).astype(np.float32),
        expression_parameters=rng.normal(size=(frames, 50)).astype(np.float32) if model_type == "smplx" else None,
        **blocks,
    )
    theirs.write(str(tmp_path / "b.smpl"))
    ours = read_smpl(tmp_path / "b.smpl")
    assert (ours.model_type, ours.gender, ours.frame_count, ours.fps) == (model_type, "female", frames, 60.0)
    assert ours.codec_version == smplcodec.version.MAJOR
    np.testing.assert_array_equal(ours.betas, theirs.shape_parameters)
    np.testing.assert_array_equal(ours.transl, theirs.body_translation)
    for name, value in blocks.items():
        np.testing.assert_array_equal(getattr(ours, name), value)
    motion = ours.to_motion()
    np.testing.assert_allclose(motion.poses, theirs.full_pose.reshape(frames, -1), **F32)
    if model_type == "smplx":
        np.testing.assert_array_equal(ours.expression, theirs.expression_parameters)
        assert motion.expression.shape == (frames, 50)
    # and back: our write of what we read is what they wrote
    write_smpl(tmp_path / "c.smpl", ours)
    assert smplcodec.SMPLCodec.from_file(str(tmp_path / "c.smpl")) == theirs


def test_shape_only_file_is_one_rest_frame(tmp_path):
    smplcodec = _codec()
    smplcodec.SMPLCodec(smpl_version=smplcodec.SMPLVersion.SMPLX, shape_parameters=np.ones(10, np.float32)).write(
        str(tmp_path / "shape.smpl")
    )
    ours = read_smpl(tmp_path / "shape.smpl")
    assert ours.frame_count is None and ours.transl is None
    motion = ours.to_motion()
    assert motion.poses.shape == (1, 165) and not motion.poses.any()
    np.testing.assert_array_equal(motion.betas, np.ones(10))


@pytest.mark.parametrize("model_type", ["smplh", "smplx"])
def test_amass_to_smpl_and_back(tmp_path, model_type):
    motion = _motion(model_type)
    save_motion(motion, tmp_path / "amass.npz")
    amass_to_smpl(tmp_path / "amass.npz", tmp_path / "m.smpl")
    smpl_to_amass(tmp_path / "m.smpl", tmp_path / "back.npz")
    back = load_motion(tmp_path / "back.npz")
    assert (back.model_type, back.gender, back.fps, back.num_frames) == (
        model_type,
        motion.gender,
        motion.fps,
        motion.num_frames,
    )
    np.testing.assert_allclose(back.poses, motion.poses, **F32)
    np.testing.assert_allclose(back.trans, motion.trans, **F32)
    np.testing.assert_allclose(back.betas, motion.betas, **F32)
    if model_type == "smplx":
        np.testing.assert_allclose(back.expression, motion.expression, **F32)
    # smplcodec's own AMASS conversion of the same file gives what ours wrote (it does not read expressions)
    smplcodec = _codec()
    theirs = smplcodec.SMPLCodec.from_amass_npz(str(tmp_path / "amass.npz"))
    ours = smplcodec.SMPLCodec.from_file(str(tmp_path / "m.smpl"))
    assert (theirs.smpl_version, theirs.frame_count, theirs.frame_rate) == (
        ours.smpl_version,
        ours.frame_count,
        ours.frame_rate,
    )
    np.testing.assert_allclose(theirs.full_pose, ours.full_pose, **F32)
    np.testing.assert_allclose(theirs.body_translation, ours.body_translation, **F32)
    np.testing.assert_allclose(theirs.shape_parameters, ours.shape_parameters, **F32)


def test_smpl_file_is_an_export_input(tmp_path):
    from smplcore.export import load_input

    motion = _motion("smplh")
    write_smpl(tmp_path / "in.smpl", SmplFile.from_motion(motion))
    got = load_input(tmp_path / "in.smpl")
    np.testing.assert_allclose(got.poses, motion.poses, **F32)
    assert got.fps == motion.fps and got.model_type == "smplh"


def test_parameter_set_with_pca_hands_through_the_model(tmp_path, fake_models):
    """A fit result (PCA hands, the mean hand pose) is written as absolute axis-angle: the .smpl motion on a
    flat-hand, full-pose model gives the vertices of the original model and parameters."""
    pca = smplcore.BodyModel(fake_models["smplx_neutral_npz"], use_pca=True, num_pca_comps=6, flat_hand_mean=False)
    rng = np.random.default_rng(1)
    params = {
        "betas": rng.normal(size=(1, 10)),
        "global_orient": rng.normal(0, 0.3, (2, 3)),
        "body_pose": rng.normal(0, 0.3, (2, 63)),
        "left_hand_pose": rng.normal(0, 0.5, (2, 6)),
        "right_hand_pose": rng.normal(0, 0.5, (2, 6)),
        "jaw_pose": rng.normal(0, 0.1, (2, 3)),
        "transl": rng.normal(0, 0.5, (2, 3)),
    }
    save_smpl(tmp_path / "fit.smpl", params, pca)
    motion = read_smpl(tmp_path / "fit.smpl").to_motion()
    assert motion.model_type == "smplx" and motion.num_frames == 2 and motion.fps == 30.0
    flat = smplcore.BodyModel(fake_models["smplx_neutral_npz"], use_pca=False, flat_hand_mean=True)
    got = flat(**motion.model_params("smplx")).vertices
    expected = pca(**params).vertices
    assert float(np.abs(got - expected).max()) < 1e-4
    with pytest.raises(ValueError, match="model: a parameter set needs its body model"):
        save_smpl(tmp_path / "x.smpl", params)


def test_what_the_format_cannot_hold_is_said(tmp_path):
    motion = dataclasses.replace(_motion("smplh"), dmpls=np.ones((9, 8)))
    with pytest.warns(UserWarning, match="no DMPL soft tissue: dropping"):
        SmplFile.from_motion(motion)
    mano = make_motion("mano", seconds=0.1, num_betas=10)
    with pytest.raises(ValueError, match="holds SMPL, SMPL\\+H and SMPL-X poses .*'mano'"):
        SmplFile.from_motion(mano)


def _savez(path, allow_pickle=False, **arrays):
    with open(path, "wb") as fh:  # np.savez would add ".npz" to a path
        np.savez(fh, allow_pickle=allow_pickle, **arrays)


def test_bad_files_name_the_key(tmp_path):
    good = SmplFile.from_motion(_motion("smplx"))
    arrays = {"smplVersion": np.int32(2), "frameCount": np.int32(9), "frameRate": np.float32(30)}
    _savez(tmp_path / "shape.smpl", bodyPose=np.zeros((9, 21, 3), np.float32), **arrays)
    with pytest.raises(ModelFileError, match=r"\[key 'bodyPose'\]: expected shape \(9, 22, 3\)"):
        read_smpl(tmp_path / "shape.smpl")
    _savez(tmp_path / "rate.smpl", smplVersion=np.int32(2), frameCount=np.int32(9))
    with pytest.raises(ModelFileError, match=r"\[key 'frameRate'\]"):
        read_smpl(tmp_path / "rate.smpl")
    _savez(tmp_path / "obj.smpl", gender=np.array([{"evil": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(ModelFileError, match=r"\[key 'gender'\]: unreadable without pickle"):
        read_smpl(tmp_path / "obj.smpl")
    _savez(tmp_path / "text.smpl", gender=np.array("male"))
    with pytest.raises(ModelFileError, match=r"\[key 'gender'\]: expected an integer"):
        read_smpl(tmp_path / "text.smpl")
    assert good.codec_version == 2


# --------------------------------------------------------------------------------------- Blender add-on npz


def test_blender_npz_layout_round_trips_y_up(tmp_path):
    motion = _motion("smplx")
    path = save_blender_npz(tmp_path / "anim.npz", motion)
    with np.load(path, allow_pickle=False) as npz:
        assert npz["poses"].shape == (motion.num_frames, 165)
        assert float(npz["mocap_frame_rate"]) == motion.fps and str(npz["gender"]) == "neutral"
        assert {"poses", "trans", "betas", "gender", "mocap_frame_rate"} <= set(npz.files)
    back = load_blender_npz(path)
    np.testing.assert_array_equal(back.poses, motion.poses)
    np.testing.assert_array_equal(back.trans, motion.trans)


def test_blender_npz_z_up_turns_the_body_like_amass(tmp_path, fake_models):
    """``up="z"`` (anim_format AMASS): the file's motion poses the model into the Y-up body turned +90 deg about X,
    and reading it back with ``up="z"`` gives the motion again."""
    model = smplcore.BodyModel(fake_models["smplh_female_npz"], use_pca=False, flat_hand_mean=True, num_betas=10)
    motion = dataclasses.replace(_motion("smplh"), gender="female")
    path = save_blender_npz(tmp_path / "z.npz", motion, up="z", model=model)
    z_up = load_blender_npz(path)  # as stored
    assert z_up.poses.shape[1] == 156
    y_vertices = model(**motion.model_params("smplh")).vertices
    z_vertices = model(**z_up.model_params("smplh")).vertices
    np.testing.assert_allclose(z_vertices, y_vertices @ Y_TO_Z_UP.T, atol=1e-5, rtol=0)
    assert z_vertices[..., 2].max() - z_vertices[..., 2].min() > 1.0  # tall along Z
    back = load_blender_npz(path, up="z", model=model)
    np.testing.assert_allclose(back.trans, motion.trans, atol=1e-9)
    np.testing.assert_allclose(model(**back.model_params("smplh")).vertices, y_vertices, atol=1e-5, rtol=0)
    with pytest.raises(ValueError, match="model: turning a motion"):
        save_blender_npz(tmp_path / "z2.npz", motion, up="z")


def test_blender_npz_from_smpl_is_smplh(tmp_path):
    motion = _motion("smpl")
    with pytest.warns(UserWarning, match="left_hand/right_hand"):
        path = save_blender_npz(tmp_path / "s.npz", motion)
    back = load_blender_npz(path)
    assert back.model_type == "smplh" and back.poses.shape[1] == 156
    np.testing.assert_array_equal(back.poses[:, :66], motion.poses[:, :66])  # pelvis .. right_wrist
