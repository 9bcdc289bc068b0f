"""Model files in, :class:`ModelData` out: safe readers for every official layout and smplcore's own; and the one
entry for auxiliary files (priors, regressors, keypoints, UVs, render inputs), read with the same bounds
(:mod:`smplcore.io.aux_files`)."""

from smplcore.io.aux_files import (
    numeric_array,
    open_input,
    read_arrays,
    read_checkpoint,
    read_json,
    read_npz,
    read_text,
)
from smplcore.io.budgets import MAX_ARRAY_ELEMENTS
from smplcore.io.model_data import MODEL_TYPES, ModelData
from smplcore.io.model_files import load_model
from smplcore.io.npz_writer import convert, save_npz
from smplcore.io.safe_pickle import UnsafePickleError, safe_load
from smplcore.io.torch_file import load_torch_file

__all__ = [
    "MAX_ARRAY_ELEMENTS",
    "MODEL_TYPES",
    "ModelData",
    "UnsafePickleError",
    "convert",
    "load_model",
    "load_torch_file",
    "numeric_array",
    "open_input",
    "read_arrays",
    "read_checkpoint",
    "read_json",
    "read_npz",
    "read_text",
    "safe_load",
    "save_npz",
]
