"""smplcore: the SMPL family of body models (SMPL, SMPL+H, SMPL-X, MANO, FLAME), fast, exact and safe.

``import smplcore`` needs only NumPy and SciPy. The PyTorch front end (``smplcore.create``,
``smplcore.SMPL``, ...) is imported on first use.
"""

from __future__ import annotations

from typing import Any

from smplcore.errors import ModelFileError, ShapeError
from smplcore.io import ModelData, convert, load_model, save_npz
from smplcore.numpy_model import BodyModel, BodyOutput

__version__ = "0.1.0"

_TORCH_NAMES = {
    "create",
    "build_layer",
    "SMPL",
    "SMPLH",
    "SMPLX",
    "MANO",
    "FLAME",
    "SMPLLayer",
    "SMPLHLayer",
    "SMPLXLayer",
    "MANOLayer",
    "FLAMELayer",
    "OpenModel",
    "ModelOutput",
    "SMPLOutput",
    "SMPLHOutput",
    "SMPLXOutput",
    "MANOOutput",
    "FLAMEOutput",
}

__all__ = [
    "BodyModel",
    "BodyOutput",
    "ModelData",
    "ModelFileError",
    "ShapeError",
    "convert",
    "install_as_smplx",
    "load_model",
    "save_npz",
    *sorted(_TORCH_NAMES),
]


_LAZY_SUBMODULES = {
    "view",
    "keypoints",
    "frontend",
    "fit",
    "smplx_compat",
    "body_models",
    "lbs",
    "utils",
    "vertex_ids",
    "joint_names",
    "vertex_joint_selector",
    "torch",
    "motion",
    "export",
    "render",
    "join",
    "uv",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY_SUBMODULES:
        import importlib

        return importlib.import_module(f"smplcore.{name}")
    if name in _TORCH_NAMES:
        try:
            import smplcore.torch as torch_front_end
        except ModuleNotFoundError as exc:
            if (exc.name or "").split(".")[0] != "torch":
                raise
            from smplcore._deps import TORCH_INSTALL, MissingDependencyError

            raise MissingDependencyError(
                f"smplcore.{name} is the PyTorch front end and needs torch, which is not installed; install it "
                f"with: {TORCH_INSTALL} (or any torch>=2.1). Without torch, smplcore.BodyModel evaluates the same "
                "models with NumPy: smplcore.BodyModel(model_path, model_type, ...)",
                module="torch",
                purpose=f"smplcore.{name}",
                extra="torch",
            ) from None
        return getattr(torch_front_end, name)
    raise AttributeError(f"module 'smplcore' has no attribute {name!r}")


def install_as_smplx() -> None:
    """Register smplcore under the name ``smplx`` (submodules included), for unmodified smplx code."""
    from smplcore.smplx_compat import install_as_smplx as _install

    _install()
