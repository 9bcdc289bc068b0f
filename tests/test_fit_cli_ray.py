"""``smplcore fit --ray``: a folder of inputs as Ray tasks on a local Ray instance."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.cli import main
from smplcore.fit.priors import joint_limits

try:
    import ray
except ImportError as exc:  # optional dependency
    pytest.skip(f"Ray is not installed ({exc}); pip install ray to run the Ray tests", allow_module_level=True)

pytestmark = pytest.mark.ray


def test_ray_fits_a_folder_and_skips_bad_inputs(tmp_path, capsys):
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    inputs = tmp_path / "in"
    inputs.mkdir()
    lo, hi = joint_limits(list(model.skeleton_joint_names[1:24]))  # poses a body can take (limits are on)
    for i in range(2):
        pose = np.clip(np.random.default_rng(i).normal(0, 0.2, (3, 23, 3)), lo, hi).reshape(3, 69)
        np.save(inputs / f"j{i}.npy", np.asarray(model(body_pose=pose).joints, np.float64)[:, :22])
    np.save(inputs / "bad.npy", np.full((2, 22, 3), np.nan))
    out = tmp_path / "out"
    assert not ray.is_initialized()
    assert main(["fit", str(inputs), "-o", str(out), "--ray", "--workers", "2"]) == 1
    text = capsys.readouterr()
    assert "2 fitted, 1 skipped" in text.out and "bad.npy" in text.err
    for i in range(2):
        with np.load(out / f"j{i}.npz") as data:
            assert data["fit_error"].max() < 0.005
