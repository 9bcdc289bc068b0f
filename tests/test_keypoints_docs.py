"""Every ```python block of docs/keypoints.md runs verbatim, and its figures exist and are small."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "keypoints.md"
BLOCKS = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_docs_python_block_runs(index, capsys):
    code = BLOCKS[index]
    if code.startswith("# illustration"):
        pytest.skip("illustration")
    exec(compile(code, f"{DOC.name}[block {index}]", "exec"), {"__name__": "__docs__"})
    assert capsys.readouterr().out.strip()  # each block prints what it shows


def test_docs_figures_exist_and_are_small():
    images = re.findall(r"\]\((keypoints/[^)]+\.png)\)", DOC.read_text())
    assert len(images) >= 15
    for image in images:
        path = DOC.parent / image
        assert path.exists(), image
        assert path.stat().st_size < 150_000, image
