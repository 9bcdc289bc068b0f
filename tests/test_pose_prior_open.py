"""smplcore's open pose prior (``GMMPrior.open()``, src/smplcore/data/pose_prior_open.npz) and the tool that
builds it (tools/train_pose_prior.py, run in its ``--quick`` mode only where the shared mocap exists)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from smplcore.fit import GMMPrior

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "src" / "smplcore" / "data" / "pose_prior_open.npz"
MOCAP = ROOT.parent / "shared" / "data" / "mocap"
BODY_JOINTS = (
    "left_hip right_hip spine1 left_knee right_knee spine2 left_ankle right_ankle spine3 left_foot right_foot neck "
    "left_collar right_collar head left_shoulder right_shoulder left_elbow right_elbow left_wrist right_wrist "
    "left_hand right_hand"
).split()


def pose(**rotations: tuple[float, float, float]) -> np.ndarray:
    """(69,) SMPL body pose with the named joints' axis-angle values in degrees (the rest elsewhere)."""
    out = np.zeros((23, 3))
    for name, value in rotations.items():
        out[BODY_JOINTS.index(name)] = np.radians(value)
    return out.ravel()


ARMS_DOWN = {"left_shoulder": (0, 0, -70), "right_shoulder": (0, 0, 70)}
NATURAL = {
    "standing, arms down": pose(**ARMS_DOWN),
    "walking step": pose(left_hip=(-25, 0, 0), right_hip=(15, 0, 0), right_knee=(35, 0, 0), left_knee=(10, 0, 0),
                         left_elbow=(0, -20, 0), right_elbow=(0, 20, 0), **ARMS_DOWN),
    "sitting": pose(left_hip=(-90, 0, 0), right_hip=(-90, 0, 0), left_knee=(90, 0, 0), right_knee=(90, 0, 0),
                    **ARMS_DOWN),
}  # fmt: skip
IMPOSSIBLE = {
    "spine folded forward": pose(spine1=(60, 0, 0), spine2=(60, 0, 0), spine3=(60, 0, 0), **ARMS_DOWN),
    "head thrown back": pose(neck=(-90, 0, 0), head=(-60, 0, 0), **ARMS_DOWN),
    "knees bent backwards": pose(left_knee=(-70, 0, 0), right_knee=(-70, 0, 0), **ARMS_DOWN),
    "elbows bent the wrong way": pose(left_elbow=(0, 90, 0), right_elbow=(0, -90, 0), **ARMS_DOWN),
    "head turned round": pose(neck=(0, 100, 0), head=(0, 80, 0), **ARMS_DOWN),
}


def cost(prior: GMMPrior, theta: np.ndarray) -> float:
    """The prior's cost of one pose: ``½|Lᵀ(θ − μ)|² + penalty`` of the best component."""
    best, res, _ = prior.residuals(theta[None, : prior.dim])
    return float(0.5 * np.sum(res**2) + prior.penalty[best[0]])


def test_the_shipped_prior_has_the_stated_shapes_finite_values_and_positive_definite_covariances():
    with np.load(DATA, allow_pickle=False) as data:
        means, covars, weights = data["means"], data["covars"], data["weights"]
        names = [str(n) for n in data["joint_names"]]
    k = len(weights)
    assert k >= 1 and means.shape == (k, 69) and covars.shape == (k, 69, 69)
    assert names == BODY_JOINTS
    assert np.all(np.isfinite(means)) and np.all(np.isfinite(covars))
    assert np.isclose(weights.sum(), 1.0) and np.all(weights > 0)
    np.testing.assert_allclose(covars, np.swapaxes(covars, 1, 2), atol=1e-12)
    assert np.linalg.eigvalsh(covars).min() > 0
    assert DATA.stat().st_size < 2_000_000  # parameters only, no motion


def test_the_shipped_prior_states_its_provenance_licence_and_held_out_subjects():
    with np.load(DATA, allow_pickle=False) as data:
        text = str(data["provenance"])
    assert "mocap.cs.cmu.edu" in text and "NSF EIA-0196217" in text  # CMU's requested acknowledgement
    assert "AnimatedDrawings" in text and "MIT" in text
    assert "not reselling" in text
    facts = json.loads(text[text.index("{") :])
    assert facts["command"].startswith("python tools/train_pose_prior.py")
    assert set(facts["subjects"]["held_out"]).isdisjoint(facts["subjects"]["train"])
    assert facts["chosen_components"] == len(np.load(DATA)["weights"])
    assert str(facts["chosen_components"]) in facts["mixtures"]


def test_open_loads_the_shipped_prior_for_smpl_and_its_marginal_for_21_joint_models():
    prior = GMMPrior.open()
    assert prior.dim == 69 and prior.source.endswith("pose_prior_open.npz")
    body = prior.marginal(63)
    assert body.dim == 63 and body.means.shape[0] == prior.means.shape[0]
    # the marginal of each Gaussian: its covariance is the leading block of the full one
    with np.load(DATA) as data:
        full = data["covars"][0, :63, :63]
    precision = body.chol[0] @ body.chol[0].T
    np.testing.assert_allclose(np.linalg.inv(precision), full, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("dim", [69, 63])
def test_natural_poses_cost_less_than_folded_or_impossible_ones(dim):
    prior = GMMPrior.open().marginal(dim)
    worst_natural = max(cost(prior, p) for p in NATURAL.values())
    for name, p in IMPOSSIBLE.items():
        assert cost(prior, p) > worst_natural, name
    assert cost(prior, NATURAL["standing, arms down"]) < cost(prior, pose())  # arms down: likelier than a T-pose


@pytest.mark.slow
@pytest.mark.skipif(not (MOCAP / "index.csv").exists(), reason="the shared mocap folder is absent (clean checkout)")
def test_the_training_tool_runs_end_to_end_on_a_few_clips(tmp_path):
    pytest.importorskip("sklearn", reason="the tool's mixtures need scikit-learn (pip install smplcore[tools])")
    out, report = tmp_path / "prior.npz", tmp_path / "report.json"
    cmd = [sys.executable, str(ROOT / "tools" / "train_pose_prior.py"), "--quick", "-q", "--mocap", str(MOCAP),
           "--out", str(out), "--report", str(report)]  # fmt: skip
    subprocess.run(cmd, check=True, timeout=900)
    facts = json.loads(report.read_text())
    assert facts["subjects"]["held_out"] and set(facts["subjects"]["held_out"]).isdisjoint(facts["subjects"]["train"])
    assert facts["frames"]["train"] > 100 and facts["frames"]["held_out"] > 100
    assert facts["retarget"]["joint_error_p95_mm"] < 5.0  # the model's own skeleton, re-posed: reached exactly
    assert all(np.isfinite(v["held_out_loglik"]) for v in facts["mixtures"].values())
    with np.load(out, allow_pickle=False) as data:
        prior = GMMPrior.from_arrays(data["means"], data["covars"], data["weights"], str(out))
    assert prior.dim == 69


def test_fit_joints_uses_the_open_prior_by_name_and_reaches_a_natural_pose():
    import smplcore
    from smplcore import fit

    model = smplcore.BodyModel(model_type="open")
    target = model(body_pose=NATURAL["walking step"][None]).joints[:, :22]
    r = fit.fit_joints(model, target, gmm="open")
    assert np.all(np.isfinite(r.params["body_pose"]))
    assert float(r.joint_error.max()) < 0.01  # metres: the prior does not pull a natural pose off its targets
