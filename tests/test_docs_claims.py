"""Figures and signatures the docs state in prose or comments, which running their blocks does not check
(issue 31, item 5)."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import numpy as np

import smplcore

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_keypoints_md_states_the_vertices_its_regressors_use():
    from smplcore import keypoints

    text = (DOCS / "keypoints.md").read_text()
    stated = re.search(r"# \(1, 42, 3\) from ([\d,]+) of the 13,380 vertices", text)
    assert stated, "docs/keypoints.md: the comment on the appended regressors' vertices"
    extra = keypoints.load_regressors({"h36m17": "open", "openpose25": "open"}, num_vertices=13380)
    assert int(stated.group(1).replace(",", "")) == len(np.unique(extra.vertex_ids)) == len(extra.vertex_ids)
    assert smplcore.BodyModel(model_type="open").faces.max() + 1 == 13380


def test_render_md_shows_render_to_png_in_its_current_order():
    from smplcore.render import render_to_png

    text = (DOCS / "render.md").read_text()
    shown = re.search(r"`render_to_png\(([^)]*)\)`", text)
    assert shown, "docs/render.md: the table row of render_to_png"
    documented = [a.strip() for a in shown.group(1).split(",")][:3]
    assert documented == list(inspect.signature(render_to_png).parameters)[:3]


def test_fit_md_shows_the_world_of_a_2d_fit_in_a_small_picture():
    text = (DOCS / "fit.md").read_text()
    assert "](fit_frames.png)" in text and "tools/render_fit_frames.py" in text
    picture = DOCS / "fit_frames.png"
    assert picture.exists() and picture.stat().st_size < 300_000


def test_readme_setup_names_what_the_demo_writes_and_what_the_tests_need(tmp_path):
    """The setup text names the demo's files and the pose in body.obj (tests/test_demo.py checks the
    texture files), that the browser tests need Chromium and how long the suite takes; the two setup commands
    stay as .ci/run greps them."""
    from smplcore.demo import DEFAULT_POSES, run_demo

    readme = (DOCS.parent / "README.md").read_text()
    setup = readme[readme.index("## Setup") : readme.index("## Use")]
    for words in ("body.obj", "body.mtl", "body_texture.png", "body.png", "A-pose", "Chromium", "15 minutes"):
        assert words in setup, words
    assert 'pip install -e ".[demo]" && smplcore demo' in setup
    assert 'pip install torch==2.13.0 && pip install -e ".[test]" && python -m pytest -q' in setup
    assert DEFAULT_POSES[0] == "a-pose"
    result = run_demo(tmp_path, render=False, texture=None)  # body.obj: the first body (A-pose)
    written = np.array([[float(v) for v in line.split()[1:4]] for line in result.mesh_path.read_text().splitlines()
                        if line.startswith("v ")])  # fmt: skip
    np.testing.assert_allclose(written, result.vertices[0], atol=1e-5)
