"""Model files in, :class:`ModelData` out: safe readers for every official layout and smplcore's own.

This package's names are io's public entry for everything above it: model files (:func:`load_model`,
:func:`read_model`, :func:`locate_model_file`) and auxiliary files (regressors, GMM and VPoser weights,
correspondences, DMPL, keypoints, UVs, motions, render inputs) through the same safe readers: regular files only,
under a :class:`LoadBudget`, lists checked (:func:`read_arrays`, :func:`read_json`, :func:`read_text`,
:func:`read_npz`, :func:`read_checkpoint`, :func:`numeric_array`, :func:`open_input`; see
:mod:`smplcore.io.aux_files`), and :func:`read_container`, :func:`read_array_file`, :func:`safe_load`,
:func:`load_torch_file`. Consumers import from here, never from io's modules.
"""

from smplcore.io.aux_files import (
    numeric_array,
    open_input,
    read_arrays,
    read_checkpoint,
    read_json,
    read_npz,
    read_text,
)
from smplcore.io.budgets import MAX_ARRAY_ELEMENTS, LoadBudget
from smplcore.io.containers import LazyNpz, read_array_file, read_container
from smplcore.io.locate import OPEN_MODEL_PATH, locate_model_file, read_model
from smplcore.io.model_data import MODEL_TYPES, ModelData
from smplcore.io.model_files import load_model
from smplcore.io.npz_writer import convert, save_npz
from smplcore.io.open_ages import age_for_stature
from smplcore.io.safe_pickle import UnsafePickleError, materialize, safe_load
from smplcore.io.torch_file import load_torch_file

__all__ = [
    "MAX_ARRAY_ELEMENTS",
    "MODEL_TYPES",
    "OPEN_MODEL_PATH",
    "LazyNpz",
    "LoadBudget",
    "ModelData",
    "UnsafePickleError",
    "age_for_stature",
    "convert",
    "load_model",
    "load_torch_file",
    "locate_model_file",
    "materialize",
    "numeric_array",
    "open_input",
    "read_array_file",
    "read_arrays",
    "read_checkpoint",
    "read_container",
    "read_json",
    "read_model",
    "read_npz",
    "read_text",
    "safe_load",
    "save_npz",
]
