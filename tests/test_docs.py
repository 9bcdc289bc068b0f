"""Docs are tests: every fenced ``python`` block of README.md and docs/*.md runs verbatim, each on its own, as
a script (``__main__``) in an empty folder that holds a ``models/`` folder of fake official files (laid out as
smplx expects). A block that cannot run starts with ``# illustration``.

A block must not print a warning it does not show: a warning on its stderr fails it, unless its fence names the
category, as in ```` ```python warns=ShapeSpaceWarning ```` (a comma-separated allow-list; Markdown renders the
fence as plain Python)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import fakes

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```python([^\n]*)\n(.*?)^```", re.S | re.M)
# What a user sees of a warning: Python's "file:line: Category: message" line
WARNING_LINE = re.compile(r"^\S.*?:\d+: (\w*Warning): (.*)$", re.M)


def _blocks() -> list[tuple[str, str, frozenset[str]]]:
    out = []
    for doc in DOCS:
        for i, match in enumerate(FENCE.finditer(doc.read_text())):
            info, code = match.group(1), match.group(2)
            allowed = re.search(r"warns=(\S+)", info)
            if not code.lstrip().startswith("# illustration"):
                names = frozenset(allowed.group(1).split(",")) if allowed else frozenset()
                out.append((f"{doc.relative_to(ROOT)}#{i + 1}", code, names))
    return out


def unexpected_warnings(stderr: str, allowed: frozenset[str]) -> list[str]:
    """The warning lines of ``stderr`` whose category is not in ``allowed``."""
    return [m.group(0) for m in WARNING_LINE.finditer(stderr) if m.group(1) not in allowed]


def test_a_printed_warning_is_caught_unless_allowed():
    stderr = (
        "/tmp/x/example.py:3: ShapeSpaceWarning: betas: the motion's betas are SMPL shape coefficients\n"
        "  model(**params)\n"
        "/usr/lib/torch/nn.py:12: UserWarning: something else\n"
    )
    assert unexpected_warnings(stderr, frozenset({"ShapeSpaceWarning"})) == [
        "/usr/lib/torch/nn.py:12: UserWarning: something else"
    ]
    assert len(unexpected_warnings(stderr, frozenset())) == 2
    assert unexpected_warnings("(2, 13380, 3)\n", frozenset()) == []


@pytest.fixture(scope="module")
def models_folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("docs-models")
    fakes.write_all(root / "models")
    return root / "models"


@pytest.mark.parametrize("name,code,allowed", _blocks(), ids=[n for n, _, _ in _blocks()])
def test_documented_example_runs(name, code, allowed, models_folder, tmp_path):
    (tmp_path / "models").symlink_to(models_folder, target_is_directory=True)
    script = tmp_path / "example.py"
    script.write_text(code)
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), PYOPENGL_PLATFORM=os.environ.get("PYOPENGL_PLATFORM", "egl"))
    result = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600
    )
    assert result.returncode == 0, f"{name} failed:\n{code}\n--- stderr ---\n{result.stderr[-3000:]}"
    unexpected = unexpected_warnings(result.stderr, allowed)
    assert not unexpected, f"{name} printed warnings it does not show:\n" + "\n".join(unexpected)
