"""Reading model files: every official layout, no chumpy, nothing executed, clear errors."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

import smplcore
from smplcore.errors import ModelFileError
from smplcore.io import convert, load_model, safe_load
from smplcore.io.safe_pickle import UnsafePickleError

SRC = Path(__file__).resolve().parents[1] / "src"


@pytest.mark.parametrize(
    "key,model_type,num_verts,num_joints,num_betas,num_expr",
    [
        ("smpl_neutral_pkl", "smpl", 6890, 24, 300, 0),
        ("smpl_neutral_npz", "smpl", 6890, 24, 300, 0),
        ("smpl_male_pkl", "smpl", 6890, 24, 10, 0),
        ("official_smpl_f_v1_0_pkl", "smpl", 6890, 24, 10, 0),
        ("official_smpl_neutral_v1_1_pkl", "smpl", 6890, 24, 300, 0),
        ("smplh_neutral_pkl", "smplh", 6890, 52, 10, 0),
        ("smplh_female_npz", "smplh", 6890, 52, 16, 0),
        ("official_smplh_male_pkl", "smplh", 6890, 52, 10, 0),
        ("official_smplh_amass_neutral_npz", "smplh", 6890, 52, 16, 0),
        ("smplx_neutral_npz", "smplx", 10475, 55, 300, 100),
        ("smplx_neutral_pkl", "smplx", 10475, 55, 300, 100),
        ("smplx_male_npz", "smplx", 10475, 55, 10, 10),
        ("mano_right_pkl", "mano", 778, 16, 10, 0),
        ("mano_left_pkl", "mano", 778, 16, 10, 0),
        ("flame_neutral_pkl", "flame", 5023, 5, 300, 100),
        ("official_flame_generic_pkl", "flame", 5023, 5, 300, 100),
    ],
)
def test_every_official_layout_loads_with_its_type_from_the_file(
    fake_models, key, model_type, num_verts, num_joints, num_betas, num_expr
):
    data = load_model(fake_models[key])
    assert data.model_type == model_type
    assert data.v_template.shape == (num_verts, 3)
    assert data.num_joints == num_joints and data.parents[0] == -1
    assert data.num_betas == num_betas and data.num_expression_coeffs == num_expr
    assert data.J_regressor.shape == (num_joints, num_verts)
    np.testing.assert_allclose(data.weights.sum(axis=1), 1.0, atol=1e-6)


def test_official_file_names_tell_gender_and_side(fake_models):
    assert load_model(fake_models["official_smpl_f_v1_0_pkl"]).gender == "female"
    assert load_model(fake_models["mano_left_pkl"]).gender == "left"
    assert load_model(fake_models["mano_right_pkl"]).gender == "right"
    assert load_model(fake_models["smplh_female_npz"]).gender == "female"


def test_pkl_and_npz_of_the_same_model_give_the_same_arrays(fake_models):
    a, b = load_model(fake_models["smpl_neutral_pkl"]), load_model(fake_models["smpl_neutral_npz"])
    for name in ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "faces", "parents"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-12)


def test_flame_landmarks_come_from_the_embedding_files(fake_models):
    data = load_model(fake_models["official_flame_generic_pkl"].parent.parent.parent / "flame" / "FLAME_NEUTRAL.pkl")
    assert data.lmk_faces_idx.shape == (51,) and data.lmk_bary_coords.shape == (51, 3)
    assert data.dynamic_lmk_faces_idx.shape == (79, 17) and data.dynamic_lmk_bary_coords.shape == (79, 17, 3)


def test_model_data_is_read_only(fake_models):
    data = load_model(fake_models["mano_right_pkl"])
    with pytest.raises(ValueError):
        data.v_template[0, 0] = 1.0


def test_loading_needs_no_chumpy(fake_models):
    """In a process where ``import chumpy`` fails, every pickle with chumpy objects still loads."""
    paths = [
        str(fake_models[k])
        for k in (
            "smpl_neutral_pkl",
            "official_smplh_male_pkl",
            "mano_left_pkl",
            "smplx_neutral_pkl",
            "official_flame_generic_pkl",
        )
    ]
    script = textwrap.dedent(f"""
        import sys
        sys.modules["chumpy"] = None  # any import of chumpy now raises ImportError
        import smplcore
        for path in {paths!r}:
            data = smplcore.load_model(path)
            print(data.model_type)
        assert "chumpy" not in {{k for k, v in sys.modules.items() if v is not None}}
    """)
    env = dict(os.environ, PYTHONPATH=str(SRC))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["smpl", "smplh", "mano", "smplx", "flame"]


class _RunsShell:
    def __init__(self, marker: str):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


class _Evals:
    def __reduce__(self):
        return (eval, ("__import__('os').getcwd()",))


@pytest.mark.parametrize("payload", ["system", "eval", "nested"])
def test_a_malicious_pickle_raises_and_runs_nothing(tmp_path, payload):
    marker = tmp_path / "pwned"
    evil = {"system": _RunsShell(str(marker)), "eval": _Evals()}.get(payload)
    if payload == "nested":
        evil = {"v_template": np.zeros((3, 3)), "shapedirs": [_RunsShell(str(marker))]}
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    path.write_bytes(pickle.dumps(evil if isinstance(evil, dict) else {"f": evil}, protocol=2))
    with pytest.raises(ModelFileError, match="refused to load.*nothing in the file was run"):
        load_model(path)
    with pytest.raises(ModelFileError):
        smplcore.BodyModel(path)
    assert not marker.exists()


def test_safe_load_refuses_globals_outside_the_allow_list():
    with pytest.raises(UnsafePickleError, match="subprocess.Popen"):
        safe_load(b"\x80\x02csubprocess\nPopen\nq\x00.")
    assert safe_load(pickle.dumps({"a": np.arange(3)}, protocol=2))["a"].tolist() == [0, 1, 2]


def test_sparse_and_plain_values_round_trip_through_safe_load():
    import scipy.sparse as sp

    value = {"J": sp.csc_matrix(np.eye(3)), "s": {1, 2}, "t": (1.5, "x")}
    out = safe_load(pickle.dumps(value, protocol=2))
    assert sp.issparse(out["J"]) and np.array_equal(out["J"].toarray(), np.eye(3))
    assert out["s"] == {1, 2} and out["t"] == (1.5, "x")


def _rewrite_npz(src: Path, dst: Path, change) -> Path:
    with np.load(src) as data:
        arrays = {k: data[k] for k in data.files}
    change(arrays)
    np.savez(dst, **arrays)
    return dst


def test_missing_key_names_file_and_key(fake_models, tmp_path):
    path = _rewrite_npz(fake_models["smpl_neutral_npz"], tmp_path / "SMPL_NEUTRAL.npz", lambda a: a.pop("weights"))
    with pytest.raises(ModelFileError, match=r"SMPL_NEUTRAL\.npz \[key 'weights'\]: missing key"):
        load_model(path)


def test_mis_shaped_key_names_expected_and_found_shapes(fake_models, tmp_path):
    path = _rewrite_npz(
        fake_models["smpl_neutral_npz"], tmp_path / "SMPL_NEUTRAL.npz", lambda a: a.update(weights=a["weights"][:, :20])
    )
    with pytest.raises(ModelFileError, match=r"\[key 'weights'\]: expected shape \(6890, 24\).*found \(6890, 20\)"):
        load_model(path)


def test_unknown_keys_in_an_official_file_warn_by_name(fake_models, tmp_path):
    path = _rewrite_npz(
        fake_models["smpl_neutral_npz"], tmp_path / "SMPL_NEUTRAL.npz", lambda a: a.update(mystery=np.zeros(3))
    )
    with pytest.warns(UserWarning, match="mystery"):
        load_model(path)


def test_faces_out_of_range_are_rejected(fake_models, tmp_path):
    def corrupt(a):
        a["f"] = a["f"].copy()
        a["f"][0, 0] = 99999

    path = _rewrite_npz(fake_models["smpl_neutral_npz"], tmp_path / "SMPL_NEUTRAL.npz", corrupt)
    with pytest.raises(ModelFileError, match=r"\[key 'f'\]: indices must lie in \[0, 6890\)"):
        load_model(path)


def test_model_type_contradicting_the_contents_is_rejected(fake_models):
    with pytest.raises(ModelFileError, match="model_type='smplx' needs 55 joints.*52-joint SMPL\\+H"):
        load_model(fake_models["smplh_neutral_pkl"], model_type="smplx")


@pytest.mark.parametrize("key", ["smpl_neutral_pkl", "smplx_neutral_npz"])
def test_truncated_files_are_reported(fake_models, tmp_path, key):
    src = fake_models[key]
    path = tmp_path / src.name
    path.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
    with pytest.raises(ModelFileError, match="truncated or corrupt"):
        load_model(path)


def test_wrong_file_types_are_reported(tmp_path):
    text = tmp_path / "SMPL_NEUTRAL.pkl"
    text.write_text("this is not a model")
    with pytest.raises(ModelFileError, match="not a model file"):
        load_model(text)
    with pytest.raises(ModelFileError, match="no such file"):
        load_model(tmp_path / "missing.pkl")
    zipped = tmp_path / "other.npz"
    with zipfile.ZipFile(zipped, "w") as archive:
        archive.writestr("hello.txt", "hi")
    with pytest.raises(ModelFileError):
        load_model(zipped)


@pytest.mark.parametrize(
    "key",
    [
        "smpl_neutral_pkl",
        "official_smplh_amass_neutral_npz",
        "smplx_neutral_pkl",
        "mano_left_pkl",
        "official_flame_generic_pkl",
    ],
)
def test_convert_writes_a_pickle_free_npz_with_the_same_model(fake_models, tmp_path, key):
    out = convert(fake_models[key], tmp_path / "model.npz")
    with np.load(out, allow_pickle=False) as data:
        assert str(data["format"]) == "smplcore-model-1"
        _ = {k: data[k] for k in data.files}  # every key loads without pickle
    original, converted = load_model(fake_models[key]), load_model(out)
    assert converted.model_type == original.model_type and converted.gender == original.gender
    for name in (
        "v_template",
        "shapedirs",
        "exprdirs",
        "posedirs",
        "J_regressor",
        "weights",
        "lmk_faces_idx",
        "dynamic_lmk_bary_coords",
        "hands_components_left",
        "hands_mean_right",
    ):
        a, b = getattr(original, name), getattr(converted, name)
        assert (a is None) == (b is None), name
        if a is not None:
            np.testing.assert_array_equal(a, b)


def test_smplcore_npz_rejects_unknown_keys(fake_models, tmp_path):
    out = convert(fake_models["mano_right_pkl"], tmp_path / "mano.npz")
    _rewrite_npz(out, tmp_path / "mano2.npz", lambda a: a.update(surprise=np.zeros(1)))
    with pytest.raises(ModelFileError, match="unknown key"):
        load_model(tmp_path / "mano2.npz")


def test_cli_convert(fake_models, tmp_path, capsys):
    from smplcore.cli import main

    assert main(["convert", str(fake_models["smplh_neutral_pkl"]), str(tmp_path / "h.npz")]) == 0
    assert "wrote" in capsys.readouterr().out
    assert load_model(tmp_path / "h.npz").model_type == "smplh"
    assert main(["convert", str(tmp_path / "missing.pkl"), str(tmp_path / "x.npz")]) == 2
    assert "no such file" in capsys.readouterr().err
