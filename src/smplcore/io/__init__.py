"""Model files in, :class:`ModelData` out: safe readers for every official layout and smplcore's own."""

from smplcore.io.model_data import MODEL_TYPES, ModelData
from smplcore.io.model_files import load_model
from smplcore.io.npz_writer import convert, save_npz
from smplcore.io.open_ages import age_for_stature
from smplcore.io.safe_pickle import UnsafePickleError, safe_load
from smplcore.io.torch_file import load_torch_file

__all__ = [
    "MODEL_TYPES",
    "ModelData",
    "UnsafePickleError",
    "age_for_stature",
    "convert",
    "load_model",
    "load_torch_file",
    "safe_load",
    "save_npz",
]
