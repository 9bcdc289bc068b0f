"""Docs are tests: every fenced ``python`` block of README.md and docs/*.md runs verbatim, each on its own, as
a script (``__main__``) in an empty folder that holds a ``models/`` folder of fake official files (laid out as
smplx expects). A block that cannot run starts with ``# illustration``."""

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
FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.S | re.M)


def _blocks() -> list[tuple[str, str]]:
    out = []
    for doc in DOCS:
        for i, match in enumerate(FENCE.finditer(doc.read_text())):
            code = match.group(1)
            if not code.lstrip().startswith("# illustration"):
                out.append((f"{doc.relative_to(ROOT)}#{i + 1}", code))
    return out


@pytest.fixture(scope="module")
def models_folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("docs-models")
    fakes.write_all(root / "models")
    return root / "models"


@pytest.mark.parametrize("name,code", _blocks(), ids=[n for n, _ in _blocks()])
def test_documented_example_runs(name, code, models_folder, tmp_path):
    (tmp_path / "models").symlink_to(models_folder, target_is_directory=True)
    script = tmp_path / "example.py"
    script.write_text(code)
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), PYOPENGL_PLATFORM=os.environ.get("PYOPENGL_PLATFORM", "egl"))
    result = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600
    )
    assert result.returncode == 0, f"{name} failed:\n{code}\n--- stderr ---\n{result.stderr[-3000:]}"
