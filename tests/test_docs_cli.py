"""Docs are tests, CLI half: every ``smplcore ...`` line of a fenced ``bash`` block in README.md and docs/*.md
runs in-process (``smplcore.cli.main``), each in its own empty folder that holds small versions of the files
the documented lines name (``walk.npz``, ``params.npz``, ``skin.png``, ``fit.npz``, ``target.npy``, ``amass/``,
``models/`` of fake official files, ``smplcore fit``'s ``openpose_frames/``, ``inputs/``, a fake ``V02_05/``,
...). A line exits 0 and writes the file (or folder) it names after ``-o``; files a line writes are not
linked into its folder beforehand. The few lines that cannot run here are listed in SKIP, each with the
reason."""

from __future__ import annotations

import re
import shlex
import types
from pathlib import Path

import numpy as np
import pytest

import fakes
from fakes_dmpl import write_dmpl
from smplcore.cli import main
from smplcore.motion.synthetic import write_sequence

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```bash[^\n]*\n(.*?)^```", re.S | re.M)

# Lines that cannot run in a test, by prefix; keep this short and say why.
# (``smplcore view`` serves until Ctrl-C: it runs here up to the point where it serves, then gets the Ctrl-C.)
SKIP = {
    "smplcore demo": "renders a sequence of poses; tests/test_demo.py runs it, --texture FILE included",
    "smplcore fit inputs/ -o fits/ --image-size 1920,1080 --ray": "starts a local Ray instance; "
    "tests/test_fit_cli_ray.py runs smplcore fit --ray on a folder of inputs",
}


# Lines that are meant to print a warning, by prefix: the words the warning must hold, and why. Any other
# warning (Python's, or the CLI's "warning:" lines on stderr) fails the line: the docs do not show it.
_AMASS_ON_OPEN = (
    ("another shape space",),
    "walk.npz is an AMASS SMPL+H motion on the open model: docs/export.md and docs/view.md show the betas warning",
)
_BVH_OWN_BONES = (
    ("target bones are not the model's",),
    "run.bvh is walk.npz exported with its own shape: fit_joints says which of its bones the open model's best "
    "body (|betas| <= 3) misses (BoneLengthWarning)",
)
WARNS: dict[str, tuple[tuple[str, ...], str]] = {
    "smplcore fit run.bvh": _BVH_OWN_BONES,
    "smplcore export walk.npz -o walk.smpl": (
        ("no DMPL soft tissue",),
        "docs/export.md's .smpl example prints the same note (a .smpl has no soft tissue)",
    ),
    "smplcore export walk.npz -o walk.bvh": _AMASS_ON_OPEN,  # a BVH has no mesh: no DMPL note
    "smplcore export walk.npz -o walk_cm.bvh": _AMASS_ON_OPEN,
    "smplcore export walk.npz --model-path": _AMASS_ON_OPEN,
    "smplcore export walk.npz -o walk.glb --model-path": (
        ("DMPL soft-tissue",),
        "docs/export.md shows the DMPL note of an AMASS motion exported without --dmpl",
    ),
    "smplcore export walk.npz": (
        ("another shape space", "DMPL soft-tissue"),
        "docs/export.md shows both notes of an AMASS motion on the open model without --dmpl",
    ),
    "smplcore view walk.npz": _AMASS_ON_OPEN,
    "smplcore render walk.npz": _AMASS_ON_OPEN,
}

# Categories Python hides from a command-line user by default (not printed, so not checked)
_HIDDEN = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


def unexpected_warnings(line: str, caught: list, stderr: str) -> list[str]:
    """The warnings a documented line printed (Python's, and the CLI's ``warning:`` lines) that it is not
    listed in WARNS for."""
    shown = [f"{w.category.__name__}: {w.message}" for w in caught if not issubclass(w.category, _HIDDEN)]
    shown += [text for text in stderr.splitlines() if re.search(r"(^|: )warning: ", text)]
    allowed = next((words for prefix, (words, _) in WARNS.items() if line.startswith(prefix)), ())
    return [text for text in shown if not any(word in text for word in allowed)]


def _lines() -> list[tuple[str, str]]:
    out = []
    for doc in DOCS:
        for block in FENCE.finditer(doc.read_text()):
            text = re.sub(r"\s*\\\n\s*", " ", block.group(1))  # a line continued with a backslash is one line
            for raw in text.splitlines():
                line = raw.split(" #", 1)[0].strip()  # the documented lines' comments follow " #"
                if line.startswith("smplcore "):
                    out.append((f"{doc.relative_to(ROOT)}: {line}", line))
    return out


LINES = _lines()


def _write_png(path: Path, size: int = 16) -> None:
    from PIL import Image

    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 255, (size, size, 3), dtype=np.uint8)).save(path)


def _write_fit_inputs(root: Path) -> None:
    """docs/fit.md's inputs, small: a person seen for 3 frames and two people in one image by a 1920 x 1080
    camera (f = 1000 px, 1 px noise) as OpenPose frames and a COCO file, the person's COCO-17 joints, a
    3-frame SMPL+H motion, a folder of three inputs, a fake VPoser v2 (written with torch) and a fake GMM."""
    import smplcore
    from fakes_fit2d import natural_poses, scene, write_coco, write_fake_gmm, write_openpose
    from smplcore import fit
    from smplcore import keypoints as kp

    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    camera = fit.Camera(focal=1000.0, center=(960.0, 540.0))
    rng = np.random.default_rng(2)
    clip = {k: np.repeat(v, 3, 0) for k, v in natural_poses(model, 1, rng).items()}
    clip["body_pose"] = clip["body_pose"] + np.linspace(0.0, 0.1, 3)[:, None]
    frames, _, _ = scene(model, clip, rng, convention="openpose25", camera=camera)
    people, _, _ = scene(model, natural_poses(model, 2, rng), rng, camera=camera)
    joints = np.asarray(model(**clip).joints, np.float64)
    write_openpose(root / "openpose_frames", frames)
    write_coco(root / "person_keypoints.json", people, 1920, 1080)
    np.save(root / "joints.npy", kp.convert(joints, model, "coco17")[0])
    write_sequence(root / "motion.npz", 3, fps=30.0, model_type="smplh", gender="neutral")
    write_openpose(root / "inputs" / "clip", frames[:2])
    write_coco(root / "inputs" / "people.json", people, 1920, 1080)
    np.save(root / "inputs" / "walk.npy", joints[:, :22])
    write_fake_gmm(root / "gmm_08.pkl")
    level = np.diag([1.0, -1.0, -1.0])  # a level camera 1.2 m up, looking along -Z, for --extrinsics
    np.save(root / "camera.npy", np.vstack([np.c_[level, -level @ [0.0, 1.2, 0.0]], [0.0, 0.0, 0.0, 1.0]]))
    try:
        from fakes_vposer import reference, write_folder

        write_folder(root / "V02_05", reference(seed=1))
    except ImportError:  # no torch: the --vposer line is skipped
        pass


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    """The files the documented lines refer to, small: 12-frame motions, one-row parameter sets, a 16x16 PNG."""
    root = tmp_path_factory.mktemp("docs-cli-inputs")
    fakes.write_all(root / "models")
    fakes.write_smplx(root / "models" / "smplx", gender="female")  # docs/view.md opens a female SMPL-X
    # docs/motion.md: AMASS's layout of the SMPL+H and DMPL downloads, an AMASS tree under two names
    (root / "models" / "smplh" / "female").mkdir()
    (root / "models" / "smplh" / "female" / "model.npz").symlink_to(root / "models" / "smplh" / "SMPLH_FEMALE.npz")
    write_dmpl(root / "models" / "dmpls" / "female", name="model.npz")
    write_sequence(root / "walk.npz", 12, fps=30.0, model_type="smplh")
    write_sequence(root / "walk_poses.npz", 12, fps=30.0, model_type="smplh")
    write_sequence(root / "amass" / "CMU" / "walk_poses.npz", 12, fps=30.0, model_type="smplh")
    (root / "amass_data").symlink_to(root / "amass", target_is_directory=True)
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
    _write_fit_inputs(root)
    return root


def _outputs(args: list[str]) -> list[str]:
    """The files (folders: ending in ``/``) a line names as its output: after ``-o``, or the last argument of
    ``convert``."""
    named = [args[i + 1] for i, a in enumerate(args[:-1]) if a in ("-o", "--output")]
    if args[0] == "convert":
        named.append(args[-1])
    return named


def _ctrl_c(seconds: float) -> None:
    raise KeyboardInterrupt


def test_a_warning_a_line_does_not_show_is_caught():
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.warn("betas: another shape space", UserWarning, stacklevel=1)
        warnings.warn("old API", DeprecationWarning, stacklevel=1)
    assert unexpected_warnings("smplcore export x", caught, "") == ["UserWarning: betas: another shape space"]
    printed = "smplcore process: warning: betas: another shape space\nprocess: 100%\n"
    assert unexpected_warnings("smplcore process a b", [], printed) == [printed.splitlines()[0]]
    assert unexpected_warnings("smplcore export x", [], "warning: dropping\n") == ["warning: dropping"]


@pytest.mark.parametrize("line", [line for _, line in LINES], ids=[name for name, _ in LINES])
def test_documented_cli_line_runs(line, inputs, tmp_path, monkeypatch, capsys):
    reason = next((why for prefix, why in SKIP.items() if line.startswith(prefix)), None)
    if reason:
        pytest.skip(reason)
    args = shlex.split(line)[1:]
    outputs = _outputs(args)
    for item in inputs.iterdir():
        if item.name not in {name.rstrip("/") for name in outputs}:  # `fit -o fit.npz` would keep an existing one
            (tmp_path / item.name).symlink_to(item, target_is_directory=item.is_dir())
    (tmp_path / "body_models").symlink_to(inputs / "models", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SMPLCORE_CACHE", str(tmp_path / "cache"))  # fit's computed correspondences, not ~/.cache
    import smplcore.frontend.setup
    import smplcore.motion.sequence

    # warnings said once per process: each line shows its own, whatever ran before it
    monkeypatch.setattr(smplcore.motion.sequence, "_warned_shape_space", set())
    monkeypatch.setattr(smplcore.frontend.setup, "_warned", set())
    if "--vposer" in args:
        pytest.importorskip("torch", reason="the fake VPoser checkpoint is written with torch")
    if args[0] == "view":
        pytest.importorskip("viser", reason="smplcore view needs the view extra")
        import smplcore.view.cli

        # the user presses Ctrl-C once it serves (the module's own `time`, not the shared one, is replaced)
        monkeypatch.setattr(smplcore.view.cli, "time", types.SimpleNamespace(sleep=_ctrl_c))
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        status = main(args)
    captured = capsys.readouterr()
    assert status == 0, line
    unexpected = unexpected_warnings(line, caught, captured.err)
    assert not unexpected, f"{line} printed warnings the docs do not show:\n" + "\n".join(unexpected)
    printed = captured.out
    if args[0] == "view":
        assert re.search(r"serving (1 body|([2-9]|[1-9]\d+) bodies) at http://", printed), printed
    if args[0] == "process":
        written = [p for p in Path(args[2]).rglob("*") if p.suffix in (".npz", ".npy")]
        assert len(written) == 1, f"{line}: {written}"
        if "--vertices" in args:
            assert "vertices" in np.load(written[0]), f"{line}: {written}"
        if "--recipe" in args:  # humanml3d: the 52 SMPL+H joints of every int(30 / 20) = 1st frame
            assert np.load(written[0]).shape == (12, 52, 3), f"{line}: {written}"
    if args[0] == "fit":
        assert re.search(r"^[1-9]\d* fitted, 0 skipped", printed, re.M), printed
    for name in outputs:
        written = sorted((tmp_path / name).glob("*.npz")) if name.endswith("/") else [tmp_path / name]
        assert written and all(p.is_file() and p.stat().st_size > 0 for p in written), f"{line}: {name} not written"
        if args[0] == "fit":
            for path in written:
                with np.load(path) as data:
                    assert np.all(np.isfinite(data["fit_error"])), f"{line}: {path.name}"


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
