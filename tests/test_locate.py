"""One model locator (``smplcore.io.locate``) behind every entry point: ``create``, ``BodyModel``, ``demo``,
``export`` and ``process`` find the file that is there, and say what they looked for when it is not."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from smplcore import BodyModel
from smplcore.cli import main
from smplcore.errors import ModelFileError
from smplcore.io.locate import OPEN_MODEL_PATH, default_ext, locate_model_file, official_names
from smplcore.motion.synthetic import write_sequence


def _link(src: Path, dst: Path) -> Path:
    """``src``'s bytes under the name ``dst`` (a small download folder built from the session's fakes)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_bytes(Path(src).read_bytes())
    return dst


@pytest.fixture(scope="module")
def downloads(fake_models, tmp_path_factory) -> dict[str, Path]:
    """Model files under the names the downloads use, flat in one folder (no ``<model_type>/`` sub-folder),
    plus an AMASS ``body_models`` tree (``smplh/<gender>/model.npz``)."""
    root = tmp_path_factory.mktemp("downloads")
    flat = root / "flat"
    p = {"flat": flat, "amass": root / "body_models"}
    p["smpl_f"] = _link(fake_models["official_smpl_f_v1_0_pkl"], flat / "basicModel_f_lbs_10_207_0_v1.0.0.pkl")
    p["smpl_n"] = _link(
        fake_models["official_smpl_neutral_v1_1_pkl"], flat / "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl"
    )
    p["smplh_m"] = _link(fake_models["official_smplh_male_pkl"], flat / "SMPLH_male.pkl")
    p["smplx_n"] = _link(fake_models["smplx_neutral_npz"], flat / "SMPLX_NEUTRAL.npz")
    p["mano_r"] = _link(fake_models["mano_right_pkl"], flat / "MANO_RIGHT.pkl")
    p["flame_n"] = _link(fake_models["official_flame_generic_pkl"], flat / "generic_model.pkl")
    amass = fake_models["official_smplh_amass_neutral_npz"]
    p["amass_n"] = _link(amass, root / "body_models" / "smplh" / "neutral" / "model.npz")
    p["amass_m"] = _link(amass, root / "body_models" / "smplh" / "male" / "model.npz")
    p["bare_f"] = _link(amass, root / "bare" / "female" / "model.npz")  # <folder>/<gender>/model.npz
    return p


@pytest.mark.parametrize(
    ("model_type", "gender", "key"),
    [
        ("smpl", "female", "smpl_f"),
        ("smpl", "neutral", "smpl_n"),
        ("smplh", "male", "smplh_m"),
        ("smplx", "neutral", "smplx_n"),
        ("mano", "neutral", "mano_r"),
        ("flame", "neutral", "flame_n"),
    ],
)
def test_official_download_names_are_found_in_a_flat_folder(downloads, model_type, gender, key):
    assert locate_model_file(downloads["flat"], model_type, gender=gender) == downloads[key]


def test_the_amass_layouts(downloads):
    amass = downloads["amass"]
    assert locate_model_file(amass, "smplh", gender="neutral") == downloads["amass_n"]
    assert locate_model_file(amass, "smplh", gender="male") == downloads["amass_m"]
    assert locate_model_file(amass / "smplh", "smplh", gender="male") == downloads["amass_m"]
    assert locate_model_file(downloads["amass"].parent / "bare", "smplh", gender="female") == downloads["bare_f"]


def test_smplx_default_ext_first_then_the_other_format(fake_models, tmp_path):
    root = fake_models["root"]  # smplx/ holds SMPLX_NEUTRAL.npz and .pkl; smpl/ holds SMPL_NEUTRAL.pkl and .npz
    assert (default_ext("smplx"), default_ext("smplh"), default_ext("smpl")) == ("npz", "pkl", "pkl")
    assert locate_model_file(root, "smplx").name == "SMPLX_NEUTRAL.npz"
    assert locate_model_file(root, "smplx", ext="pkl").name == "SMPLX_NEUTRAL.pkl"
    assert locate_model_file(root, "smpl").name == "SMPL_NEUTRAL.pkl"
    assert locate_model_file(root, "smpl", ext=".NPZ").name == "SMPL_NEUTRAL.npz"
    only_npz = _link(fake_models["smpl_neutral_npz"], tmp_path / "smpl" / "SMPL_NEUTRAL.npz")
    assert locate_model_file(tmp_path, "smpl") == only_npz  # pkl asked (the default), npz is what is there
    assert locate_model_file(tmp_path / "smpl", "smpl", ext="pkl") == only_npz
    with pytest.raises(ValueError, match="ext: expected 'pkl' or 'npz', got 'obj'"):
        locate_model_file(tmp_path, "smpl", ext="obj")


def test_names_match_without_regard_to_case_and_the_newest_version_wins(fake_models, tmp_path):
    old = _link(fake_models["official_smpl_f_v1_0_pkl"], tmp_path / "BASICMODEL_F_LBS_10_207_0_V1.0.0.PKL")
    assert locate_model_file(tmp_path, "smpl", gender="female") == old
    new = _link(fake_models["official_smpl_f_v1_0_pkl"], tmp_path / "basicmodel_f_lbs_10_207_0_v1.1.0.pkl")
    assert locate_model_file(tmp_path, "smpl", gender="female") == new
    assert official_names("flame", "male", "pkl") == ["FLAME_MALE.pkl", "male_model.pkl"]


def test_not_found_lists_what_was_looked_for_and_the_fix(downloads):
    with pytest.raises(ModelFileError) as info:
        locate_model_file(downloads["amass"], "smplx", gender="female")
    text = str(info.value)
    assert "no female SMPL-X model (model_type='smplx', gender='female', ext='npz')" in text
    for name in ("SMPLX_FEMALE.npz", "female/model.npz", "SMPLX_FEMALE.pkl"):
        assert name in text  # what was looked for
    assert "model files here: smplh/male/model.npz, smplh/neutral/model.npz" in text
    example = downloads["amass"] / "smplx" / "SMPLX_FEMALE.npz"
    assert f"To fix: put the official SMPL-X file there (e.g. {example})" in text
    assert "pass the file itself as model_path" in text
    with pytest.raises(ModelFileError, match="no left MANO model .*is_rhand='left'"):
        locate_model_file(downloads["flat"], "mano", is_rhand=False)
    with pytest.raises(ModelFileError, match="no such file or folder"):
        locate_model_file(downloads["flat"] / "missing", "smpl")


# ---------------------------------------------------------------------------------------------------
# every entry point goes through it


def test_body_model_and_create(downloads):
    torch = pytest.importorskip("torch")
    import smplcore

    model = BodyModel(downloads["flat"], "smpl", gender="female")
    assert model.setup.data.source == str(downloads["smpl_f"]) and model.setup.data.gender == "female"
    module = smplcore.create(downloads["flat"], model_type="smpl", gender="female")
    assert module.setup.data.source == str(downloads["smpl_f"])
    ours = model(betas=np.full((1, 10), 0.3)).vertices
    with torch.no_grad():
        theirs = module(betas=torch.full((1, 10), 0.3)).vertices.numpy()
    np.testing.assert_allclose(theirs, ours, atol=1e-5)
    amass = smplcore.create(downloads["amass"], model_type="smplh", gender="male", use_pca=False)
    assert amass.setup.data.source == str(downloads["amass_m"])


def test_demo_on_an_amass_smplh_folder_with_ext_and_use_pca(downloads, tmp_path, capsys):
    """The AMASS SMPL+H npz has no hand PCA: the demo works (use_pca is then off by default)."""
    out = tmp_path / "demo"
    argv = ["demo", "--out", str(out), "--model-path", str(downloads["amass"]), "--model-type", "smplh"]
    assert main([*argv, "--gender", "male", "--no-render", "--format", "ply"]) == 0
    assert (out / "body.ply").stat().st_size > 6890 * 12
    assert main([*argv, "--no-render", "--format", "ply", "--ext", "npz", "--no-use-pca"]) == 0
    capsys.readouterr()
    assert main([*argv, "--no-render", "--format", "ply", "--use-pca"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "use_pca=True needs the left hand's PCA components" in err
    assert "pass use_pca=False" in err


def test_demo_without_the_file_says_what_it_looked_for(downloads, tmp_path, capsys):
    argv = ["demo", "--out", str(tmp_path / "d"), "--model-path", str(downloads["flat"]), "--model-type", "smplx"]
    assert main([*argv, "--gender", "male", "--no-render"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("smplcore demo: error: ") and "no male SMPL-X model" in err and "SMPLX_MALE.npz" in err


def test_export_finds_the_amass_model_and_honours_ext(downloads, tmp_path, capsys):
    motion = write_sequence(tmp_path / "walk.npz", 12, 30.0, "smplh", "male")
    out = tmp_path / "frame.ply"
    argv = ["export", str(motion), "-o", str(out), "--model-path", str(downloads["amass"]), "--model-type", "smplh"]
    assert main([*argv, "--ext", "npz", "--frame", "3"]) == 0
    assert "frame 3 of 12, 6890 vertices" in capsys.readouterr().out
    # the same frame posed directly on the file the locator chose
    data = np.load(motion)
    model = BodyModel(downloads["amass_m"], "smplh", gender="male", use_pca=False, flat_hand_mean=True, num_betas=16)
    expected = model(
        betas=data["betas"][None, :16],
        global_orient=data["poses"][3:4, :3],
        body_pose=data["poses"][3:4, 3:66],
        left_hand_pose=data["poses"][3:4, 66:111],
        right_hand_pose=data["poses"][3:4, 111:156],
        transl=data["trans"][3:4],
    ).vertices[0]
    import trimesh

    written = trimesh.load(out, process=False).vertices
    np.testing.assert_allclose(written, expected, atol=1e-5)
    assert main([*argv[:-2], "--model-path", str(downloads["flat"]), "--model-type", "smplx"]) == 2
    assert "no male SMPL-X model" in capsys.readouterr().err


def test_process_finds_official_names_and_amass_layouts(downloads, tmp_path):
    from smplcore.motion import ProcessOptions, process_tree

    write_sequence(tmp_path / "in" / "a_poses.npz", 20, 30.0, "smplh", "male")
    for folder, expected in ((downloads["flat"], "SMPLH_male.pkl"), (downloads["amass"], "model.npz")):
        out = tmp_path / f"out_{folder.name}"
        summary = process_tree(tmp_path / "in", out, ProcessOptions(model_path=str(folder)), workers=0, progress=False)
        assert (summary.done, summary.skipped) == (1, [])
        assert str(np.load(out / "a_poses.npz")["model_file"]) == expected
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished"


@pytest.mark.skipif(not OPEN_MODEL_PATH.exists(), reason="the open model is not built")
def test_open_model_ignores_the_folder_with_a_warning_and_picks_the_gender(tmp_path):
    with pytest.warns(UserWarning, match="model_type='open' is the packaged open model: the folder is not used"):
        assert locate_model_file(tmp_path, "open", gender="female").name == "open_model_female.npz"
    assert locate_model_file(None, "open") == OPEN_MODEL_PATH


def test_fakes_still_match_smplx_names(fake_models):
    """The fake tree is laid out as smplx expects: every file found where smplx would look."""
    root = fake_models["root"]
    assert locate_model_file(root, "mano", is_rhand=False) == fake_models["mano_left_pkl"]
    assert locate_model_file(root, "smplh", gender="female") == fake_models["smplh_female_npz"]
    assert locate_model_file(root, "flame") == fake_models["flame_neutral_pkl"]
