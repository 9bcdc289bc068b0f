"""smplx 0.1.28's module paths (``body_models``, ``lbs``, ``utils``, ``vertex_ids``, ``joint_names``,
``vertex_joint_selector``) over smplcore,
and ``install_as_smplx()``, which lets unmodified smplx code run on smplcore."""

from __future__ import annotations

import importlib
import sys

_SUBMODULES = ("body_models", "lbs", "utils", "vertex_ids", "joint_names", "vertex_joint_selector")


def install_as_smplx() -> None:
    """Register smplcore under the name ``smplx``, with ``smplx.body_models``, ``smplx.lbs``,
    ``smplx.utils``, ``smplx.vertex_ids``, ``smplx.joint_names`` and ``smplx.vertex_joint_selector``.

    After this, ``import smplx`` (and ``from smplx.lbs import vertices2joints``, subclasses of
    ``smplx.SMPL``, ...) use smplcore. Call it before anything imports smplx. Like PyMySQL's
    ``install_as_MySQLdb()``, it replaces an already imported smplx in ``sys.modules``.
    """
    package = importlib.import_module("smplcore")
    sys.modules["smplx"] = package
    for name in _SUBMODULES:
        sys.modules[f"smplx.{name}"] = importlib.import_module(f"smplcore.smplx_compat.{name}")
