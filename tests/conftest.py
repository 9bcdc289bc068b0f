"""Shared pytest fixtures."""

from __future__ import annotations

import sys
from collections import OrderedDict
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


@pytest.fixture(scope="session")
def model_cache():
    """Models built once per session and shared between tests: ``model_cache(factory, *args, **kwargs)`` returns
    ``factory(*args, **kwargs)`` (``smplcore.create``, ``smplcore.BodyModel``, ...), built on first use.

    Only for tests that do not change the model (parameters, buffers, attributes): the next test gets the same
    object. The most recently used models are kept (a bound on memory)."""
    built: OrderedDict = OrderedDict()

    def get(factory, *args, **kwargs):
        key = (factory, tuple(repr(a) for a in args), tuple(sorted((k, repr(v)) for k, v in kwargs.items())))
        if key in built:
            built.move_to_end(key)
            return built[key]
        model = built[key] = factory(*args, **kwargs)
        if len(built) > _MODEL_CACHE_SIZE:
            built.popitem(last=False)
        return model

    return get


# the models of one parametrized round (tests/test_oracle.py's torch test: 8 model files and options); an SMPL-X
# model holds a few hundred MB, so the cache stays small
_MODEL_CACHE_SIZE = 8
