"""Reading the containers model files come in (pickle, .npz, .npy) into dicts of arrays, safely."""

from __future__ import annotations

import io
import pickle
import zipfile
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.safe_pickle import UnsafePickleError, safe_load

_ZIP_MAGIC = b"PK\x03\x04"
_NPY_MAGIC = b"\x93NUMPY"


def read_container(path: str | Path) -> dict[str, Any]:
    """Read a ``.pkl``, ``.npz`` or ``.npy`` (holding a pickled dict) file into a dict.

    The kind of file is told from its first bytes, not its name. Nothing in the file is executed:
    pickles go through :func:`smplcore.io.safe_pickle.safe_load`.

    Raises
    ------
    ModelFileError
        Missing file, unknown format, truncated or corrupt data, or a pickle that asks for anything
        but arrays and sparse matrices.
    """
    path = Path(path)
    if not path.exists():
        raise ModelFileError(path, "no such file")
    if path.is_dir():
        raise ModelFileError(path, "is a directory, expected a model file")
    with open(path, "rb") as fh:
        head = fh.read(8)
        fh.seek(0)
        try:
            if head.startswith(_ZIP_MAGIC):
                return _read_npz(fh)
            if head.startswith(_NPY_MAGIC):
                value = _read_npy(fh)
                if isinstance(value, np.ndarray) and value.dtype == object and value.shape == ():
                    value = value.item()
                if not isinstance(value, dict):
                    raise ModelFileError(path, "this .npy file holds an array, not a dict of model arrays")
                return value
            if head[:1] == b"\x80" or head[:1] in (b"(", b"}"):
                value = safe_load(fh)
                if not isinstance(value, dict):
                    raise ModelFileError(path, f"the pickle holds a {type(value).__name__}, not a dict")
                return value
        except UnsafePickleError as exc:
            raise ModelFileError(path, f"refused to load: {exc}; nothing in the file was run") from None
        except ModelFileError:
            raise
        except (
            EOFError,
            pickle.UnpicklingError,
            zipfile.BadZipFile,
            ValueError,
            OSError,
            KeyError,
            TypeError,
            IndexError,
        ) as exc:
            raise ModelFileError(path, f"truncated or corrupt file ({type(exc).__name__}: {exc})") from None
    raise ModelFileError(
        path, f"not a model file: expected a pickle (.pkl) or NumPy (.npz) file, found data starting with {head[:8]!r}"
    )


def _read_npy(fh: BinaryIO) -> np.ndarray | Any:
    """Read one .npy array; object arrays are unpickled through the allow-list."""
    version = np.lib.format.read_magic(fh)
    reader = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    if version not in reader:
        raise ValueError(f"unsupported .npy version {version}")
    shape, fortran, dtype = reader[version](fh)
    if dtype.hasobject:
        return safe_load(fh)
    count = int(np.prod(shape, dtype=np.int64))
    data = fh.read(count * dtype.itemsize)
    if len(data) != count * dtype.itemsize:
        raise EOFError(f"expected {count * dtype.itemsize} bytes of array data, found {len(data)}")
    array = np.frombuffer(data, dtype=dtype, count=count)
    return array.reshape(shape[::-1]).T if fortran else array.reshape(shape)


def _read_npz(fh: BinaryIO) -> dict[str, Any]:
    out = {}
    with zipfile.ZipFile(fh) as archive:
        for name in archive.namelist():
            key = name[:-4] if name.endswith(".npy") else name
            with archive.open(name) as member:
                out[key] = _read_npy(io.BytesIO(member.read()))
    return out
