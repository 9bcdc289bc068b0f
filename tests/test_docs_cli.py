"""Docs are tests, CLI half: every ``smplcore ...`` line of a fenced ``bash`` block in README.md and docs/*.md
runs in-process (``smplcore.cli.main``), each in its own empty folder that holds small versions of the files
the documented lines name (``walk.npz``, ``params.npz``, ``skin.png``, ``fit.npz``, ``target.npy``, ``amass/``,
``models/`` of fake official files, ...). A line exits 0 and writes the file it names after ``-o``.
The few lines that cannot run here are listed in SKIP, each with the reason."""

from __future__ import annotations

import re
import shlex
import types
from pathlib import Path

import numpy as np
import pytest

import fakes
from smplcore.cli import main
from smplcore.motion.synthetic import write_sequence

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```bash[^\n]*\n(.*?)^```", re.S | re.M)

# Lines that cannot run in a test, by prefix; keep this short and say why.
# (``smplcore view`` serves until Ctrl-C: it runs here up to the point where it serves, then gets the Ctrl-C.)
SKIP = {
    "smplcore demo": "renders a sequence of poses; tests/test_demo.py runs it, --texture FILE included",
}


def _lines() -> list[tuple[str, str]]:
    out = []
    for doc in DOCS:
        for block in FENCE.finditer(doc.read_text()):
            for raw in block.group(1).splitlines():
                line = raw.split(" #", 1)[0].strip()  # the documented lines' comments follow " #"
                if line.startswith("smplcore "):
                    out.append((f"{doc.relative_to(ROOT)}: {line}", line))
    return out


LINES = _lines()


def _write_png(path: Path, size: int = 16) -> None:
    from PIL import Image

    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 255, (size, size, 3), dtype=np.uint8)).save(path)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    """The files the documented lines refer to, small: 12-frame motions, one-row parameter sets, a 16x16 PNG."""
    root = tmp_path_factory.mktemp("docs-cli-inputs")
    fakes.write_all(root / "models")
    fakes.write_smplx(root / "models" / "smplx", gender="female")  # docs/view.md opens a female SMPL-X
    write_sequence(root / "walk.npz", 12, fps=30.0, model_type="smplh")
    write_sequence(root / "amass" / "CMU" / "walk_poses.npz", 12, fps=30.0, model_type="smplh")
    rng = np.random.default_rng(1)
    params = {
        "betas": rng.normal(0.0, 1.0, (1, 10)),
        "global_orient": np.zeros((1, 3)),
        "body_pose": rng.normal(0.0, 0.2, (1, 69)),
        "transl": np.zeros((1, 3)),
    }
    np.savez(root / "params.npz", **params)
    np.savez(root / "fit.npz", **params)
    np.save(root / "target.npy", rng.normal(0.0, 0.3, (1, 24, 3)))
    _write_png(root / "skin.png")
    assert main(["export", str(root / "walk.npz"), "-o", str(root / "run.bvh")]) == 0
    return root


def _outputs(args: list[str]) -> list[str]:
    """The files a line names as its output: after ``-o``, or the last argument of ``convert``."""
    named = [args[i + 1] for i, a in enumerate(args[:-1]) if a in ("-o", "--output")]
    if args[0] == "convert":
        named.append(args[-1])
    return named


def _ctrl_c(seconds: float) -> None:
    raise KeyboardInterrupt


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("line", [line for _, line in LINES], ids=[name for name, _ in LINES])
def test_documented_cli_line_runs(line, inputs, tmp_path, monkeypatch, capsys):
    reason = next((why for prefix, why in SKIP.items() if line.startswith(prefix)), None)
    if reason:
        pytest.skip(reason)
    for item in inputs.iterdir():
        (tmp_path / item.name).symlink_to(item, target_is_directory=item.is_dir())
    (tmp_path / "body_models").symlink_to(inputs / "models", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    args = shlex.split(line)[1:]
    if args[0] == "view":
        pytest.importorskip("viser", reason="smplcore view needs the view extra")
        import smplcore.view.cli

        # the user presses Ctrl-C once it serves (the module's own `time`, not the shared one, is replaced)
        monkeypatch.setattr(smplcore.view.cli, "time", types.SimpleNamespace(sleep=_ctrl_c))
    assert main(args) == 0, line
    printed = capsys.readouterr().out
    if args[0] == "view":
        assert re.search(r"serving [1-9]\d* body\(ies\) at http://", printed), printed
    if args[0] == "process":
        written = list(Path(args[2]).rglob("*.npz"))
        assert len(written) == 1 and "vertices" in np.load(written[0]), f"{line}: {written}"
    for name in _outputs(args):
        assert (tmp_path / name).is_file() and (tmp_path / name).stat().st_size > 0, f"{line}: {name} not written"


def test_a_model_file_on_its_own_is_viewed_with_axis_angle_hands(inputs):
    """``smplcore view models/smplx/SMPLX_NEUTRAL.npz`` (model type read from the file) posed every hand joint
    with PCA coefficients and failed: (1, 45) hand poses against a (B, 6) PCA model."""
    from smplcore.view.bodies import build_model

    model = build_model(inputs / "models" / "smplx" / "SMPLX_NEUTRAL.npz")
    assert model.model_type == "smplx"
    hand = np.full((1, 45), 0.1)
    out = model(left_hand_pose=hand, right_hand_pose=hand)
    flat = model(left_hand_pose=np.zeros((1, 45)), right_hand_pose=np.zeros((1, 45)))
    assert out.vertices.shape == (1, 10475, 3) and not np.allclose(out.vertices, flat.vertices)
