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
