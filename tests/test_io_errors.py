"""Every failure while loading is a ModelFileError naming the file, the key, what was expected and
what was found: damaged archives and pickles, OS errors, and values that would otherwise load and
go wrong later (bad kintree parents, complex or float32-overflowing values, inconsistent smplcore
files)."""

from __future__ import annotations

import os
import struct
import zipfile

import numpy as np
import pytest

import hostile_files as H
import smplcore
from smplcore.errors import ModelFileError
from smplcore.io import convert, load_model, safe_load


@pytest.fixture(scope="module")
def mano_arrays(fake_models):
    """The fake MANO_RIGHT's keys as plain arrays (an official layout, 3.4 MB)."""
    raw = safe_load(fake_models["mano_right_pkl"].read_bytes())
    return {k: v.toarray() if hasattr(v, "toarray") else v for k, v in raw.items() if not isinstance(v, (str, dict))}


@pytest.fixture(scope="module")
def mano_smplcore_npz(fake_models, tmp_path_factory):
    return convert(fake_models["mano_right_pkl"], tmp_path_factory.mktemp("own") / "mano.npz")


def _official_npz(tmp_path, arrays, **changes):
    out = dict(arrays, **changes)
    path = tmp_path / "MANO_RIGHT.npz"
    np.savez(path, **out)
    return path


def _kintree(arrays, parents):
    table = arrays["kintree_table"].copy()
    table[0, : len(parents)] = parents
    return table


def _set_one(array, flat_index, value):
    out = array.copy()
    out.flat[flat_index] = value
    return out


OFFICIAL_VALUE_CASES = {
    "kintree cycle": (
        lambda a: {"kintree_table": _kintree(a, [-1, 2, 1])},
        "kintree_table",
        r"joint 1 has parent 2 \(a cycle or a later joint",
    ),
    "joint its own parent": (
        lambda a: {"kintree_table": _kintree(a, [-1, 0, 2])},
        "kintree_table",
        r"joint 2 has parent 2 \(its own parent",
    ),
    "parent after the joint": (
        lambda a: {"kintree_table": _kintree(a, [-1, 0, 1, 15])},
        "kintree_table",
        r"0 <= parent < joint\); joint 3 has parent 15",
    ),
    "negative parent": (
        lambda a: {"kintree_table": _kintree(a, [-1, 0, -3])},
        "kintree_table",
        r"joint 2 has parent -3",
    ),
    "float kintree": (
        lambda a: {"kintree_table": a["kintree_table"].astype(np.float64)},
        "kintree_table",
        r"expected integer joint indices, found dtype float64",
    ),
    "text kintree": (
        lambda a: {"kintree_table": a["kintree_table"].astype(str)},
        "kintree_table",
        r"expected a numeric array, found dtype <U\d+",
    ),
    "complex template": (
        lambda a: {"v_template": a["v_template"] + 1j},
        "v_template",
        r"expected real numbers, found complex values \(dtype complex128\)",
    ),
    "float64 beyond float32": (
        lambda a: {
            "shapedirs": np.where(
                np.arange(a["shapedirs"].size).reshape(a["shapedirs"].shape) == 7, 1e300, a["shapedirs"]
            )
        },
        "shapedirs",
        r"expected values within float32's range \(\|x\| <= 3.4e\+38\), found values in \[.*, 1e\+300\]",
    ),
    "NaN correctives": (
        lambda a: {
            "posedirs": np.where(np.arange(a["posedirs"].size).reshape(a["posedirs"].shape) == 3, np.nan, a["posedirs"])
        },
        "posedirs",
        r"contains NaN or infinite values",
    ),
    "float faces": (lambda a: {"f": a["f"].astype(np.float32)}, "f", r"expected integer indices, found dtype float32"),
    "text template": (
        lambda a: {"v_template": np.array("abc")},
        "v_template",
        r"expected a numeric array, found dtype <U3",
    ),
}


@pytest.mark.parametrize("case", list(OFFICIAL_VALUE_CASES))
def test_bad_values_in_an_official_file_name_file_key_expected_and_found(mano_arrays, tmp_path, case):
    change, key, pattern = OFFICIAL_VALUE_CASES[case]
    path = _official_npz(tmp_path, mano_arrays, **change(mano_arrays))
    with pytest.raises(ModelFileError, match=rf"MANO_RIGHT\.npz \[key '{key}'\]: .*{pattern}") as info:
        load_model(path)
    assert info.value.key == key and info.value.path == str(path)


def _rewrite(src, dst, **changes):
    with np.load(src) as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    np.savez(dst, **arrays)
    return dst


SMPLCORE_CASES = {
    "unknown model type": (
        {"model_type": np.array("bogus")},
        "model_type",
        r"expected one of \['smpl', .*found 'bogus'",
    ),
    "model type contradicting the arrays": (
        {"model_type": np.array("smplx")},
        "v_template",
        r"expected shape \(10475, 3\) for a SMPL-X model, found \(778, 3\)",
    ),
    "model type that is not a string": (
        {"model_type": np.array(["mano", "x"])},
        "model_type",
        r"expected a string \(0-d text array\), found dtype <U4, shape \(2,\)",
    ),
    "gender that is a number": (
        {"gender": np.array(3)},
        "gender",
        r"expected a string \(0-d text array\), found dtype int",
    ),
    "joint_names of the wrong length": (
        {"joint_names": np.array(["a", "b", "c"])},
        "joint_names",
        r"expected 16 names, found 3",
    ),
    "parents with a cycle": (
        {"parents": np.array([-1, 0, 1, 5, 3, 4, 0, 6, 7, 0, 9, 10, 0, 12, 13, 1])},
        "parents",
        r"joint 3 has parent 5 \(a cycle or a later joint",
    ),
    "root with a parent": (
        {"parents": np.arange(16) - 1 + (np.arange(16) == 0)},
        "parents",
        r"expected -1 as the root's parent",
    ),
}


@pytest.mark.parametrize("case", list(SMPLCORE_CASES))
def test_inconsistent_smplcore_files_are_refused(mano_smplcore_npz, tmp_path, case):
    changes, key, pattern = SMPLCORE_CASES[case]
    path = _rewrite(mano_smplcore_npz, tmp_path / "mano.npz", **changes)
    with pytest.raises(ModelFileError, match=rf"mano\.npz \[key '{key}'\]: .*{pattern}"):
        load_model(path)


def _zip_members(mano_arrays, method=zipfile.ZIP_DEFLATED):
    return [{"name": f"{k}.npy", "data": H.npy_of(v), "method": method} for k, v in mano_arrays.items()]


def test_a_flipped_byte_in_a_compressed_member_names_the_member(mano_arrays, tmp_path):
    path = tmp_path / "MANO_RIGHT.npz"
    np.savez_compressed(path, **mano_arrays)
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo("v_template.npy")
    start = info.header_offset + 30 + len(info.filename)
    for offset in (start + 50, start + info.compress_size // 2):
        data[offset] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(ModelFileError, match=r"\[key 'v_template'\]: truncated or corrupt file \((error|BadZipFile)"):
        load_model(path)


@pytest.mark.parametrize("where", ["header padding", "data", "last byte"])
def test_a_changed_byte_in_a_stored_member_is_a_crc_error(mano_arrays, tmp_path, where):
    """Stored members are read straight from the file into the array; their CRC-32 is still checked."""
    path = tmp_path / "MANO_RIGHT.npz"
    np.savez(path, **mano_arrays)
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo("shapedirs.npy")
    name_length, extra_length = struct.unpack("<HH", data[info.header_offset + 26 : info.header_offset + 30])
    start = info.header_offset + 30 + name_length + extra_length  # the member's first byte
    if where == "header padding":  # a space before the .npy header's newline becomes a tab: still a valid header
        offset = data.index(b"\n", start) - 1
        assert data[offset] == ord(" ")
        data[offset] = ord("\t")
    else:
        data[start + (info.file_size // 2 if where == "data" else info.file_size - 1)] ^= 0x01
    path.write_bytes(bytes(data))
    with pytest.raises(
        ModelFileError, match=r"\[key 'shapedirs'\]: truncated or corrupt file \(BadZipFile: Bad CRC-32"
    ):
        load_model(path)


def test_stored_members_read_in_fortran_order_and_with_bytes_after_the_array(mano_arrays, tmp_path):
    """A Fortran-order array and a member with bytes after its array (CRC over all of them) read as written."""
    arrays = dict(mano_arrays, shapedirs=np.asfortranarray(mano_arrays["shapedirs"]))
    members = _zip_members(arrays, method=0)
    target = next(m for m in members if m["name"] == "J_regressor.npy")
    target["data"] += b"\0" * 7
    path = H.write_zip(tmp_path / "MANO_RIGHT.npz", members)
    data = load_model(path)
    np.testing.assert_array_equal(data.shapedirs, mano_arrays["shapedirs"])
    np.testing.assert_array_equal(np.asarray(data.J_regressor), mano_arrays["J_regressor"])


ZIP_CASES = {
    "encrypted member": (dict(flags=1), r"\[key 'v_template'\]: the member is encrypted"),
    "bzip2 member": (dict(method=12), r"\[key 'v_template'\]: the member uses zip compression method 12"),
    "lzma member": (dict(method=14), r"compression method 14"),
    "unknown method": (dict(method=99), r"compression method 99"),
    "wrong CRC": (dict(crc=1234), r"\[key 'v_template'\]: truncated or corrupt file \(BadZipFile: Bad CRC-32"),
    "stored sizes disagree": (dict(size=10), r"\[key 'v_template'\]: a stored member's sizes disagree"),
}


@pytest.mark.parametrize("case", list(ZIP_CASES))
def test_damaged_zip_members_name_file_and_key(mano_arrays, tmp_path, case):
    change, pattern = ZIP_CASES[case]
    members = _zip_members(mano_arrays, method=0)
    target = next(m for m in members if m["name"] == "v_template.npy")
    target.update(change)
    path = H.write_zip(tmp_path / "MANO_RIGHT.npz", members)
    with pytest.raises(ModelFileError, match=pattern):
        load_model(path)


def test_archive_level_damage(mano_arrays, tmp_path):
    members = _zip_members(mano_arrays, method=0)
    whole = H.write_zip(tmp_path / "whole.npz", members).read_bytes()
    cut = tmp_path / "MANO_RIGHT.npz"
    cut.write_bytes(whole[: len(whole) // 2])
    with pytest.raises(ModelFileError, match=r"MANO_RIGHT\.npz: truncated or corrupt file \(BadZipFile"):
        load_model(cut)
    twice = H.write_zip(tmp_path / "MANO_LEFT.npz", members + members[:1])
    with pytest.raises(ModelFileError, match=r"\[key '\w+'\]: the archive holds two members of this name"):
        load_model(twice)
    header = tmp_path / "SMPL_NEUTRAL.npz"
    H.write_zip(
        header, [{"name": "v_template.npy", "data": H.npy_bytes("{'descr': '<f8', 'fortran_order': False, 'sha")}]
    )
    with pytest.raises(ModelFileError, match=r"\[key 'v_template'\]: truncated or corrupt file"):
        load_model(header)


PICKLE_CASES = {
    "integer of 5000 digits": (b"(dp0\nS'v_template'\np1\nI" + b"9" * 5000 + b"\ns.", r"ValueError.*digits"),
    "int of infinity": (
        H.dict_of(v_template=H.reduce(H.glob("__builtin__", "int"), b"G" + struct.pack(">d", float("inf")))),
        r"OverflowError: cannot convert float infinity",
    ),
    "lists nested 100000 deep": (H.PROTO2 + b"(" * 100000 + b"l" * 100000 + b".", r"values nested more than 64 deep"),
    "unknown codec": (
        H.one_value(H.reduce(H.glob("_codecs", "encode"), H.text("x"), H.text("no-such-codec"))),
        r"codec 'no-such-codec' is not allowed",
    ),
    "wrong argument count": (H.one_value(H.reduce(H.glob("numpy", "dtype"), *[H.integer(1)] * 7)), r"TypeError"),
    "append onto a dict": (H.PROTO2 + b"}K\x01a.", r"cannot add items to a dict"),
    "setitem onto a list": (H.PROTO2 + b"]K\x01K\x02s.", r"cannot add items to a list"),
    "unknown opcode": (H.PROTO2 + b"\xff.", r"UnpicklingError"),
    "memo miss": (H.PROTO2 + b"h\x07.", r"Memo value not found"),
    "stack underflow": (H.PROTO2 + b"t.", r"UnpicklingError|could not find MARK"),
    "a pickle of a list": (H.dumps([1, 2]), r"the pickle holds a list, not a dict"),
    "non-text keys": (H.dumps({1: np.zeros(3)}), r"expected text keys, found a int key"),
    "a persistent id": (H.PROTO2 + b"N" + b"Q.", r"persistent ids are not allowed"),
    "an extension code": (H.PROTO2 + b"\x82\x01.", r"extension codes"),
}


@pytest.mark.parametrize("case", list(PICKLE_CASES))
def test_damaged_pickles_give_model_file_errors(tmp_path, case):
    data, pattern = PICKLE_CASES[case]
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    path.write_bytes(data)
    with pytest.raises(ModelFileError, match=rf"SMPL_NEUTRAL\.pkl: .*{pattern}"):
        load_model(path)


def test_os_errors_while_opening_are_model_file_errors(tmp_path, monkeypatch):
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    path.write_bytes(H.dumps({"a": 1}))

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "open", refuse)
    with pytest.raises(ModelFileError, match=r"SMPL_NEUTRAL\.pkl: cannot read \(Permission denied\)"):
        load_model(path)
    monkeypatch.undo()
    monkeypatch.setattr(os, "stat", refuse)
    with pytest.raises(ModelFileError, match=r"cannot read \(Permission denied\)"):
        load_model(path)
    monkeypatch.undo()
    link = tmp_path / "SMPL_MALE.pkl"
    link.symlink_to(tmp_path / "gone.pkl")
    with pytest.raises(ModelFileError, match=r"SMPL_MALE\.pkl: no such file"):
        load_model(link)
    empty = tmp_path / "SMPL_FEMALE.pkl"
    empty.write_bytes(b"")
    with pytest.raises(ModelFileError, match=r"not a model file"):
        load_model(empty)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_an_unreadable_file_is_a_model_file_error(tmp_path):
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    path.write_bytes(H.dumps({"a": 1}))
    path.chmod(0)
    with pytest.raises(ModelFileError, match=r"cannot read \(Permission denied\)"):
        load_model(path)


class Struct:
    def __init__(self, **kwargs):
        self.__dict__.update(kwargs)


def test_a_data_struct_with_unusable_values_names_the_key(mano_arrays):
    junk = Struct(**dict(mano_arrays, v_template=[[object()] * 3] * 778))
    with pytest.raises(ModelFileError, match=r"\[key 'v_template'\]: holds Python objects"):
        smplcore.create(model_type="mano", data_struct=junk)
    odd = Struct(**dict(mano_arrays, kintree_table=np.array([[0, 0, 1], [0, 1, 2]], dtype=np.int64)[:, [0, 1, 1]]))
    with pytest.raises(ModelFileError, match=r"\[key 'kintree_table'\]"):
        smplcore.create(model_type="mano", data_struct=odd)
