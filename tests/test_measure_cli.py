"""``smplcore measure``: a table or JSON for betas, a motion .npz and a mesh file; ``--fit`` prints betas."""

from __future__ import annotations

import json

import numpy as np
import pytest

import smplcore
from smplcore.cli import main
from smplcore.measure import measure


def test_measure_prints_a_table_of_the_open_models_mean_body(capsys):
    assert main(["measure"]) == 0
    out = capsys.readouterr().out
    stature = measure(smplcore.BodyModel(model_type="open"), names=["stature"])["stature"]
    assert "stature" in out and f"{stature * 100:.1f} cm" in out
    for name in ("waist", "hip", "inseam", "bmi"):
        assert name in out


def test_measure_json_of_a_motion_npz_uses_its_betas_and_gender(tmp_path, capsys):
    betas = np.zeros((3, 16))
    betas[:, 0] = 1.5
    path = tmp_path / "motion.npz"
    np.savez(path, betas=betas[0], gender="male", poses=np.zeros((3, 72)))
    assert main(["measure", str(path), "--names", "stature,mass", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    ref = measure(smplcore.BodyModel(model_type="open", gender="male"), betas[0, :10], names=["stature", "mass"])
    assert got["units"] == {"stature": "m", "mass": "kg"}
    np.testing.assert_allclose(got["values"]["stature"], ref["stature"], rtol=1e-9)
    np.testing.assert_allclose(got["values"]["mass"], ref["mass"], rtol=1e-9)


def test_measure_a_mesh_file_of_the_models_topology(tmp_path, capsys):
    trimesh = pytest.importorskip("trimesh")
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    v = model(betas=np.full((1, 10), 0.5)).vertices[0]
    path = tmp_path / "body.ply"
    trimesh.Trimesh(v, model.faces, process=False).export(path)
    assert main(["measure", str(path), "--names", "waist", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)["values"]["waist"]
    np.testing.assert_allclose(got, measure(model, np.full(10, 0.5), names=["waist"])["waist"], rtol=1e-5)
    bad = tmp_path / "box.ply"
    trimesh.creation.box().export(bad)
    assert main(["measure", str(bad)]) == 2
    assert "13380 vertices" in capsys.readouterr().err


def test_measure_fit_prints_betas_that_reach_the_targets(capsys):
    assert main(["measure", "--fit", "height=1.80,waist=0.85", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert len(got["betas"]) == 10
    assert abs(got["residual"]["stature"]) < 0.005 and abs(got["residual"]["waist"]) < 0.01
    assert main(["measure", "--fit", "armspan=1.7"]) == 2
    assert "armspan" in capsys.readouterr().err
