"""``smplcore process --ray``: the job as Ray tasks on a local Ray instance: same outputs, same resume."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fakes
from smplcore.cli import main
from smplcore.motion import ProcessOptions, process_tree
from smplcore.motion.synthetic import random_arrays, write_tree

try:
    import ray
except ImportError as exc:  # Ray is an optional dependency
    pytest.skip(f"Ray is not installed ({exc}); pip install ray to run the Ray tests", allow_module_level=True)

pytestmark = pytest.mark.ray

GOOD = [
    ("A/one_poses.npz", 180, 120.0, "female"),
    ("A/two_poses.npz", 60, 60.0, "male"),
    ("B/three_poses.npz", 45, 30.0, "female"),
]


@pytest.fixture(scope="module")
def ray_session():
    """One local Ray instance for the module (starting Ray takes seconds)."""
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    if started:
        ray.shutdown()


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    root = tmp_path_factory.mktemp("ray")
    model = fakes.write_smplh(root / "models", "female", "npz", amass=True)
    write_tree(root / "in", GOOD)
    arrays = random_arrays(30, 60.0, "smplh", "male", seed=4)
    arrays["poses"][3, 3] = np.nan
    np.savez(root / "in" / "B" / "bad_poses.npz", **arrays)
    options = ProcessOptions(model_path=str(model), fps=20.0, backend="numpy")
    reference = root / "reference"
    assert process_tree(root / "in", reference, options, workers=0, progress=False, check=False).exit_code == 1
    return root, options, reference


def _joints(path):
    with np.load(path, allow_pickle=False) as f:
        return f["joints"]


def test_ray_same_outputs_and_resume(ray_session, job):
    root, options, reference = job
    out = root / "out"
    summary = process_tree(root / "in", out, options, ray_address="local", progress=False, check=False)
    assert summary.executor == "Ray CPUs" and summary.workers == 2
    assert (summary.done, summary.existing, summary.exit_code) == (3, 0, 1)
    assert [path for path, _ in summary.skipped] == ["B/bad_poses.npz"]
    assert "NaN" in summary.skipped[0][1] and str(root / "in" / "B" / "bad_poses.npz") in summary.skipped[0][1]
    for rel, *_ in GOOD:
        np.testing.assert_array_equal(_joints(out / rel), _joints(reference / rel))
    again = process_tree(root / "in", out, options, ray_address="local", progress=False, check=False)
    assert (again.done, again.existing, len(again.skipped)) == (0, 3, 1)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished"
    assert {e["input"]: e["status"] for e in manifest["files"]} == {
        "A/one_poses.npz": "exists",
        "A/two_poses.npz": "exists",
        "B/three_poses.npz": "exists",
        "B/bad_poses.npz": "skipped",
    }


def test_ray_cli(ray_session, job, capsys):
    root, options, reference = job
    out = root / "cli"
    assert (
        main(
            [
                "process",
                str(root / "in"),
                str(out),
                "--model-path",
                options.model_path,
                "--fps",
                "20",
                "--backend",
                "numpy",
                "--ray",
                "--quiet",
            ]
        )
        == 1
    )
    assert "4 files: 3 processed, 0 already done, 1 skipped" in capsys.readouterr().out
    for rel, *_ in GOOD:
        np.testing.assert_array_equal(_joints(out / rel), _joints(reference / rel))
