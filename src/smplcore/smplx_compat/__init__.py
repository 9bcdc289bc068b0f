"""smplx 0.1.28's module paths (``body_models``, ``lbs``, ``utils``, ``vertex_ids``, ``joint_names``) over smplcore,
and ``install_as_smplx()``, which lets unmodified smplx code run on smplcore."""

from __future__ import annotations

import importlib
import sys

_SUBMODULES = ("body_models", "lbs", "utils", "vertex_ids", "joint_names")


def install_as_smplx() -> None:
    """Register smplcore under the name ``smplx``, with ``smplx.body_models``, ``smplx.lbs``,
    ``smplx.utils``, ``smplx.vertex_ids`` and ``smplx.joint_names``.

    After this, ``import smplx`` (and ``from smplx.lbs import vertices2joints``, subclasses of
    ``smplx.SMPL``, ...) use smplcore. Call it before anything imports smplx. Like PyMySQL's
    ``install_as_MySQLdb()``, it replaces an already imported smplx in ``sys.modules``.
    """
    package = importlib.import_module("smplcore")
    sys.modules["smplx"] = package
    for name in _SUBMODULES:
        sys.modules[f"smplx.{name}"] = importlib.import_module(f"smplcore.smplx_compat.{name}")
