"""Shared pytest fixtures."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fakes


@pytest.fixture(scope="session")
def fake_models(tmp_path_factory):
    """Structurally exact fake official model files (see the ``tests/fakes/`` package), written once per
    session; returns the dict of :func:`fakes.write_all` (keys such as ``"root"``,
    ``"smpl_neutral_pkl"``, ``"smplx_neutral_npz"``, ``"mano_left_pkl"``, ...)."""
    return fakes.write_all(tmp_path_factory.mktemp("models"))
