"""Warnings name the caller's line (whatever the call path inside smplcore), a model file's harmless extra
keys do not warn, and ``render_to_png`` takes the path first (the old order still works, with a warning)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import fakes
from smplcore import BodyModel, load_model
from smplcore.io.locate import OPEN_MODEL_PATH

needs_open = pytest.mark.skipif(not OPEN_MODEL_PATH.exists(), reason="the open model is not built")
HERE = str(Path(__file__).resolve())


def _here(record: list[warnings.WarningMessage], text: str) -> warnings.WarningMessage:
    """The one warning whose message has ``text``; it must name this file."""
    hits = [w for w in record if text in str(w.message)]
    assert len(hits) == 1, [str(w.message) for w in record]
    assert str(Path(hits[0].filename).resolve()) == HERE, (hits[0].filename, hits[0].lineno)
    return hits[0]


def _smpl_with_keys(folder: Path, **extra: np.ndarray) -> Path:
    """A fake SMPL ``.npz`` with extra keys besides the model's."""
    src = fakes.write_smpl(folder / "base", "neutral", "1.0", "npz")
    with np.load(src) as z:
        arrays = dict(z)
    path = folder / "SMPL_NEUTRAL.npz"
    np.savez(path, **arrays, **extra)
    return path


@needs_open
def test_unknown_keywords_warn_at_the_callers_line():
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        model = BodyModel(model_type="open", stacklevel_probe_init=1)
        line_init = _here(record, "stacklevel_probe_init").lineno
        model(betas=np.zeros((1, 10)), stacklevel_probe_call=1)
        line_call = _here(record, "stacklevel_probe_call").lineno
    assert line_call == line_init + 2


@needs_open
def test_create_and_forward_warn_at_the_callers_line():
    torch = pytest.importorskip("torch")
    import smplcore

    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        module = smplcore.create(model_type="open", stacklevel_probe_create=1)
        _here(record, "stacklevel_probe_create")
        module(betas=torch.zeros(1, 10), stacklevel_probe_forward=1)  # through torch's Module.__call__
        _here(record, "stacklevel_probe_forward")


def test_a_files_unknown_key_warns_at_the_callers_line_and_harmless_keys_do_not(tmp_path):
    harmless = _smpl_with_keys(
        tmp_path / "a",
        betas=np.zeros(10),  # SMPLify saves a body's parameters with the model
        pose=np.zeros(72),
        trans=np.zeros(3),
        v_shaped=np.zeros((6890, 3)),  # and chumpy's derived arrays
        v_posed=np.zeros((6890, 3)),
        J_transformed=np.zeros((24, 3)),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_model(harmless).model_type == "smpl"
        assert BodyModel(harmless.parent, "smpl").num_betas == 10
    odd = _smpl_with_keys(tmp_path / "b", stacklevel_probe_key=np.zeros(3))
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        load_model(odd)
        _here(record, "ignoring keys smplcore does not know: ['stacklevel_probe_key']")
        BodyModel(odd.parent, "smpl")  # locate, read, set up: a deeper path, the same line reported
        _here(record[1:], "stacklevel_probe_key")


def test_export_warnings_name_the_callers_line(fake_models, tmp_path):
    from smplcore.export import save_glb

    model = BodyModel(fake_models["smpl_male_pkl"])  # has pose correctives, which glTF cannot express
    motion = {"body_pose": np.full((3, 69), 0.2), "betas": np.zeros((1, 10))}
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        report = save_glb(tmp_path / "a.glb", model, motion)
    _here(record, "pose-corrective blend shapes")
    assert any("pose-corrective" in n for n in report.warnings)


# ---------------------------------------------------------------------------------------------------
# render_to_png(path, vertices, faces), as save_mesh(path, vertices, faces)

TRI_V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
TRI_F = np.array([[0, 1, 2]])


@pytest.fixture(scope="module")
def gl() -> None:
    from smplcore.render import render_mesh

    try:
        render_mesh(TRI_V, TRI_F, width=8, height=8)
    except RuntimeError as exc:
        pytest.skip(f"no offscreen OpenGL (EGL/OSMesa) here: {exc}")


def test_render_to_png_takes_the_path_first_like_save_mesh(gl, tmp_path):
    import inspect

    from PIL import Image

    from smplcore.export import save_glb, save_mesh
    from smplcore.render import render_to_png

    for fn in (render_to_png, save_mesh, save_glb):
        assert next(iter(inspect.signature(fn).parameters)) == "path"
    new = render_to_png(tmp_path / "new.png", TRI_V, TRI_F, width=40, height=30)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        old = render_to_png(TRI_V, TRI_F, str(tmp_path / "old.png"), width=40, height=30)
    assert _here(record, "render_to_png(vertices, faces, path) is deprecated").category is DeprecationWarning
    assert (new, old) == (tmp_path / "new.png", tmp_path / "old.png")
    a, b = np.asarray(Image.open(new)), np.asarray(Image.open(old))
    assert a.shape == (30, 40, 3) or a.shape == (30, 40, 4)
    np.testing.assert_array_equal(a, b)
    assert a.std() > 0  # the triangle is drawn
    with pytest.raises(TypeError, match="path: expected a file name"):
        render_to_png(TRI_V, TRI_F, TRI_F)
