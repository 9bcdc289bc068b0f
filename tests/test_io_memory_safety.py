"""Forged pickles and .npy headers that used to crash the process (object dtypes forged from file
bytes, BUILD on dtypes and functions, deep tuples, out-of-range sparse indices) are refused with a
ModelFileError; loads run in a child process so a crash fails the test instead of killing pytest."""

from __future__ import annotations

import re

import numpy as np
import pytest
import scipy.sparse as sp

import hostile_files as H
from smplcore.io import safe_load
from smplcore.io.safe_pickle import UnsafePickleError

# name -> (pickle bytes of a dict holding the forged value under "v_template", expected message)
PICKLE_CASES = {
    "dtype state clearing the object flags": (
        H.ndarray_op(H.dtype_op("f8", (3, "|", None, None, None, -1, -1, 63)), (2,), bytes(16)),
        r"dtype f8 with flags 63",
    ),
    "object dtype whose flags claim plain data": (
        H.ndarray_op(H.dtype_op("O8", (3, "|", None, None, None, -1, -1, 0)), (2,), bytes(16)),
        r"dtype O8 with flags 0",
    ),
    "object array from file bytes (pointers)": (
        H.ndarray_op(H.dtype_op("O8", (3, "|", None, None, None, -1, -1, 63)), (2,), bytes(16)),
        r"object array of shape \(2,\) needs a list of 2 values",
    ),
    "structured dtype state": (
        H.ndarray_op(H.dtype_op("V8", (3, "|", None, ("a",), None, 8, 1, 0)), (2,), bytes(16)),
        r"dtype 'V8' is not a plain numeric",
    ),
    "fields set on a plain type string": (
        H.ndarray_op(H.dtype_op("f8", (3, "<", None, ("a",), None, -1, -1, 0)), (2,), bytes(16)),
        r"structured and sub-array dtypes are not allowed",
    ),
    "sub-array dtype": (
        H.ndarray_op(H.dtype_op("f8", (3, "<", ("f8", (2,)), None, None, -1, -1, 0)), (2,), bytes(16)),
        r"structured and sub-array dtypes are not allowed",
    ),
    "structured type string": (
        H.ndarray_op(H.dtype_op("f8,i4"), (2,), bytes(24)),
        r"dtype 'f8,i4' is not a plain numeric",
    ),
    "datetime dtype": (H.ndarray_op(H.dtype_op("M8"), (2,), bytes(16)), r"dtype 'M8' is not a plain"),
    "string dtype with a forged item size": (
        H.ndarray_op(H.dtype_op("U8", (3, "<", None, None, None, 3, 4, 8)), (2,), bytes(6)),
        r"invalid string dtype size 3",
    ),
    "data shorter than the shape": (
        H.ndarray_op(H.dtype_op("f8"), (10, 3), bytes(8)),
        r"needs 240 bytes, found 8",
    ),
    "data longer than the shape": (H.ndarray_op(H.dtype_op("f8"), (1,), bytes(800)), r"needs 8 bytes, found 800"),
    "negative dimension": (H.ndarray_op(H.dtype_op("f8"), (-1, 3), b""), r"negative dimension"),
    "dtype that is a plain tuple": (H.ndarray_op(H.obj(("f8",)), (1,), bytes(8)), r"dtype must come from"),
    "_frombuffer with an object dtype": (
        H.reduce(
            H.glob("numpy.core.numeric", "_frombuffer"),
            H.obj(bytes(16)),
            H.dtype_op("O8", (3, "|", None, None, None, -1, -1, 63)),
            H.obj((2,)),
            H.obj("C"),
        ),
        r"object arrays cannot be built from a buffer",
    ),
    "_frombuffer with too few bytes": (
        H.reduce(
            H.glob("numpy._core.numeric", "_frombuffer"), H.obj(bytes(4)), H.dtype_op("f8"), H.obj((4,)), H.obj("C")
        ),
        r"needs 32 bytes, found 4",
    ),
    "scalar with an object dtype": (
        H.reduce(
            H.glob("numpy.core.multiarray", "scalar"),
            H.dtype_op("O8", (3, "|", None, None, None, -1, -1, 63)),
            H.obj(bytes(8)),
        ),
        r"numpy scalars must have a plain",
    ),
    "scalar with the wrong byte count": (
        H.reduce(H.glob("numpy.core.multiarray", "scalar"), H.dtype_op("f8"), H.obj(bytes(3))),
        r"needs 8 bytes, found 3",
    ),
    "_reconstruct of another class": (
        H.reduce(H.glob("numpy.core.multiarray", "_reconstruct"), H.glob("chumpy.ch", "Ch"), H.obj((0,)), H.obj(b"b")),
        r"_reconstruct of Ch is not allowed",
    ),
    "BUILD rewriting _codecs.encode's defaults": (
        H.glob("_codecs", "encode") + b"}" + H.text("__defaults__") + H.tup(H.text("punycode")) + b"sb",
        r"setting the state of a method is not allowed",
    ),
    "BUILD on numpy.dtype itself": (
        H.glob("numpy", "dtype") + b"}" + H.text("__doc__") + H.text("x") + b"sb",
        r"setting the state of a method is not allowed",
    ),
    "BUILD on a real dtype's class marker": (H.glob("numpy", "ndarray") + b"}b", r"setting the state of a type"),
    "BUILD on a builtin list": (b"]}b", r"setting the state of a list"),
    "calling the ndarray marker": (H.reduce(H.glob("numpy", "ndarray"), H.obj((3,))), r"calling NdarrayName"),
    "NEWOBJ of builtins.object": (H.glob("__builtin__", "object") + b")\x81", r"creating a type is not allowed|object"),
    "a tuple key nested a million deep": (None, r"tuples nested more than 64 deep"),
}


def _write(tmp_path, name: str, value: bytes | None):
    path = tmp_path / f"SMPL_{re.sub(r'[^a-z0-9]+', '_', name)}.pkl"
    path.write_bytes(H.deep_tuple_key(10**6) if value is None else H.dict_of(v_template=value))
    return path


def test_forged_dtypes_and_arrays_in_pickles_are_refused(tmp_path):
    names = list(PICKLE_CASES)
    paths = [_write(tmp_path, n, PICKLE_CASES[n][0]) for n in names]
    outcomes = H.load_in_child(paths)
    for name, path, (outcome, message) in zip(names, paths, outcomes):
        assert outcome == "ModelFileError", (name, outcome, message)
        assert message.startswith(str(path)), (name, message)
        assert re.search(PICKLE_CASES[name][1], message), (name, message)


def test_a_legitimate_hand_built_array_pickle_still_loads():
    """The same opcode builders with numpy's real states give the right arrays (so the refusals
    above are about the forgeries, not the layout)."""
    values = np.arange(6, dtype=">i4").reshape(2, 3)
    stream = H.one_value(
        H.ndarray_op(H.dtype_op("i4", (3, ">", None, None, None, -1, -1, 0)), (2, 3), values.tobytes())
    )
    out = safe_load(stream)
    assert out.dtype == np.dtype(">i4") and out.tolist() == values.tolist()
    text = H.one_value(
        H.ndarray_op(H.dtype_op("U8", (3, "<", None, None, None, 8, 4, 8)), (1,), "ab".encode("utf-32-le"))
    )
    assert safe_load(text).tolist() == ["ab"]
    fortran = H.one_value(H.ndarray_op(H.dtype_op("f8"), (2, 2), np.arange(4.0).tobytes(), fortran=True))
    assert safe_load(fortran).tolist() == [[0.0, 2.0], [1.0, 3.0]]


def test_object_arrays_are_built_from_unpickled_values_only():
    value = np.empty((2,), dtype=object)
    value[0], value[1] = {"a": np.arange(2)}, "x"
    out = safe_load(H.dumps(value))
    assert out.dtype == object and out[0]["a"].tolist() == [0, 1] and out[1] == "x"


def test_build_cannot_change_allow_listed_functions():
    import codecs

    with pytest.raises(UnsafePickleError, match="setting the state"):
        safe_load(
            H.one_value(H.glob("_codecs", "encode") + b"}" + H.text("__defaults__") + H.tup(H.text("punycode")) + b"sb")
        )
    assert codecs.encode("a") == b"a"  # utf-8 default untouched
    assert safe_load(H.dumps(b"\xffbytes")) == b"\xffbytes"  # _codecs.encode(latin1) still works


def _sparse_pickle(tmp_path, name: str, change) -> object:
    m = sp.csc_matrix(np.eye(3))
    change(m)
    path = tmp_path / f"SMPL_sparse_{name}.pkl"
    path.write_bytes(H.dumps({"J_regressor": m}))
    return path


def test_sparse_matrices_with_bad_indices_are_refused_before_scipy_sees_them(tmp_path):
    cases = {
        "index_out_of_range": (
            lambda m: m.indices.__setitem__(0, 99),
            r"'indices' must lie in \[0, 3\), found \[1, 99\]",
        ),
        "negative_index": (lambda m: m.indices.__setitem__(1, -5), r"'indices' must lie in \[0, 3\)"),
        "indptr_past_the_end": (lambda m: m.indptr.__setitem__(3, 50), r"indptr must rise from 0"),
        "indptr_falling": (lambda m: m.indptr.__setitem__(1, 3), r"indptr must rise from 0"),
        "wrong_indptr_length": (lambda m: setattr(m, "indptr", m.indptr[:2]), r"indptr must have 4 entries"),
        "float_indices": (lambda m: setattr(m, "indices", m.indices.astype(float)), r"'indices' must be a 1-d integer"),
    }
    paths = [_sparse_pickle(tmp_path, name, change) for name, (change, _) in cases.items()]
    for (name, (_, pattern)), (outcome, message) in zip(cases.items(), H.load_in_child(paths)):
        assert outcome == "ModelFileError" and re.search(pattern, message), (name, outcome, message)


def test_npy_headers_with_unsafe_dtypes_are_refused(tmp_path):
    cases = {
        "object_field": (
            "{'descr': [('a', '|O')], 'fortran_order': False, 'shape': (2,), }",
            r"structured dtype with Python objects",
        ),
        "void": ("{'descr': '|V8', 'fortran_order': False, 'shape': (2,), }", r"dtype \|V8 is not a plain"),
        "structured": (
            "{'descr': [('a', '<f8'), ('b', '<i4')], 'fortran_order': False, 'shape': (2,), }",
            r"is not a plain",
        ),
        "datetime": ("{'descr': '<M8[s]', 'fortran_order': False, 'shape': (2,), }", r"is not a plain"),
        "negative_shape": ("{'descr': '<f8', 'fortran_order': False, 'shape': (-2,), }", r"negative dimension"),
    }
    paths = []
    for name, (header, _) in cases.items():
        path = tmp_path / f"{name}.npz"
        H.write_zip(path, [{"name": "v_template.npy", "data": H.npy_bytes(header, bytes(48))}])
        paths.append(path)
    for (name, (_, pattern)), (outcome, message) in zip(cases.items(), H.load_in_child(paths)):
        assert outcome == "ModelFileError" and "[key 'v_template']" in message, (name, outcome, message)
        assert re.search(pattern, message), (name, message)
