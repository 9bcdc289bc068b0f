"""Reading a file costs time and memory proportional to its size: bombs, huge declared lengths and
shapes, shared-list blow-ups, expensive codecs and non-regular files are refused with a
ModelFileError. Every load runs in a child process under RLIMIT_AS (1 GiB) and a timeout, so a
blow-up fails the test instead of the machine."""

from __future__ import annotations

import os
import re
import struct
import subprocess
import sys
import textwrap
import zipfile

import numpy as np
import pytest

import hostile_files as H
from smplcore.io.locate import OPEN_MODEL_PATH


def _pickle_file(tmp_path, name: str, data: bytes):
    path = tmp_path / f"SMPL_{name}.pkl"
    path.write_bytes(data)
    return path


PICKLE_BOMBS = {
    # name: (bytes, expected message)
    "shared_list_60_levels": (H.shared_list_bomb(60), r"\[key 'v_template'\]: a nested list with more than 1,000,000"),
    "shared_list_100_levels": (H.shared_list_bomb(100), r"values nested more than 64 deep"),
    "list_copied_20000_times": (
        H.list_copy_bomb(20000, 20000),
        r"builtins\.list would need .* at most 6\d,\d{3},\d{3} bytes in all",
    ),
    "shared_list_as_a_codec_name": (
        H.one_value(H.glob("_codecs", "encode") + b"(" + H.text("x") + H.shared_list_ops(60) + b"tR"),
        r"codec a list is not allowed",
    ),
    "punycode": (
        H.one_value(H.reduce(H.glob("_codecs", "encode"), H.text("\u00e9" * 58000), H.text("punycode"))),
        r"codec 'punycode' is not allowed",
    ),
    "bytearray_2_3_GB": (
        H.one_value(H.reduce(H.glob("__builtin__", "bytearray"), H.long_(2_300_000_000))),
        r"builtins\.bytearray with these arguments",
    ),
    "bytes_10_GB": (H.one_value(H.reduce(H.glob("builtins", "bytes"), H.long_(10**10))), r"builtins\.bytes with these"),
    "binbytes8_length_2_62": (
        b"\x80\x04\x8e" + struct.pack("<Q", 2**62) + b".",
        r"asks for 4,611,686,018,427,387,904 bytes but only 1 remain",
    ),
    "binunicode8_length_2_40": (
        b"\x80\x04\x8d" + struct.pack("<Q", 2**40) + b"ab.",
        r"asks for 1,099,511,627,776 bytes",
    ),
    "binstring_length_2_31": (b"\x80\x02T" + struct.pack("<i", 2**31 - 1) + b".", r"asks for 2,147,483,647 bytes"),
    "frame_length_2_60": (
        b"\x80\x04\x95" + struct.pack("<Q", 2**60) + b"N.",
        r"asks for 1,152,921,504,606,846,976 bytes",
    ),
    "encode_aliased_100_times": (
        H.PROTO2
        + H.text("a" * (4 << 20))
        + b"q\x00"
        + H.glob("_codecs", "encode")
        + b"q\x01]("
        + (b"h\x01h\x00" + H.text("latin1") + b"\x86R") * 100
        + b"e.",
        r"_codecs\.encode would need",
    ),
    "pickled_array_2_40_elements": (
        H.one_value(H.ndarray_op(H.dtype_op("f8"), (2**20, 2**20), b"")),
        r"declares 1,099,511,627,776 elements; no body model array has more than 134,217,728",
    ),
}


def test_pickle_bombs_are_refused_within_the_budget(tmp_path):
    paths = [_pickle_file(tmp_path, name, data) for name, (data, _) in PICKLE_BOMBS.items()]
    for (name, (_, pattern)), path, (outcome, message) in zip(PICKLE_BOMBS.items(), paths, H.load_in_child(paths)):
        assert outcome == "ModelFileError" and message.startswith(str(path)), (name, outcome, message)
        assert re.search(pattern, message), (name, message)


def test_a_shared_list_is_shared_not_copied(tmp_path):
    """2**60 leaves if copied; built once and shared, it unpickles at once."""
    script = textwrap.dedent(f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))
        sys.path.insert(0, {str(H.SRC.parent / "tests")!r})
        import hostile_files as H
        from smplcore.io import safe_load
        out = safe_load(H.shared_list_bomb(60))["v_template"]
        depth = 0
        while out:
            assert out[0] is out[1]
            out, depth = out[0], depth + 1
        print(depth)
    """)
    result = _run(script)
    assert result.stdout.split() == ["60"], result.stderr


def _run(script: str, timeout: float = 60) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(H.SRC), OPENBLAS_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=timeout)


def _open_model_members() -> list[dict]:
    with zipfile.ZipFile(OPEN_MODEL_PATH) as archive:
        return [{"name": name, "data": archive.read(name)} for name in archive.namelist()]


def _mano_npz_members(fake_models) -> list[dict]:
    """The fake MANO_RIGHT.pkl's arrays as members of an official-layout .npz (3.4 MB)."""
    from smplcore.io import safe_load

    raw = safe_load(fake_models["mano_right_pkl"].read_bytes())
    dense = {k: v.toarray() if hasattr(v, "toarray") else v for k, v in raw.items()}
    return [{"name": f"{k}.npy", "data": H.npy_of(v)} for k, v in dense.items() if isinstance(v, np.ndarray)]


def _npy_header(shape: tuple, descr: str = "<f8") -> bytes:
    return H.npy_bytes(f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}")


def _deflated(name: str, data: bytes, declared: int) -> dict:
    return {"name": name, "data": data, "method": 8, "raw": True, "size": declared}


def test_archive_bombs_are_refused_and_unused_members_never_inflated(fake_models, tmp_path):
    gib = 1 << 30
    big = 805306368
    cases = {
        # an unused 2 GiB member next to a valid model: never read, so the model loads under 1 GiB
        "unused_bomb": (
            _mano_npz_members(fake_models) + [_deflated("junk.npy", H.zeros_deflated(2 * gib), 2 * gib)],
            r"^ok",
        ),
        # a used member whose .npy header declares 805 MB, inflating for real from a 0.8 MB file
        "used_bomb": (
            [_deflated("v_template.npy", H.zeros_deflated(big, prefix=_npy_header((2**25, 3))), big + 128)],
            r"\[key 'v_template'\]: \.npy data of shape \(33554432, 3\) would need 805,306,368 bytes",
        ),
        "declared_ratio_beyond_deflate": (
            [_deflated("v_template.npy", zlib_raw(_npy_header((2, 3)) + bytes(48)), 2 * gib)],
            r"\[key 'v_template'\]: the member declares 2,147,483,648 bytes from \d+ compressed",
        ),
        "header_beyond_the_member": (
            [{"name": "v_template.npy", "data": _npy_header((2**24, 3)) + bytes(48)}],
            r"\[key 'v_template'\]: .*header declares 402,653,184 bytes of data .* holds at most 48",
        ),
        "header_of_10_12_elements": (
            [{"name": "v_template.npy", "data": _npy_header((10**12,))}],
            r"\[key 'v_template'\]: \.npy header: shape \(1000000000000,\) declares 1,000,000,000,000 elements",
        ),
        "300_members": (
            [{"name": f"m{i}.npy", "data": b""} for i in range(300)],
            r"lists 300 members; model files have at most 256",
        ),
    }
    paths = [H.write_zip(tmp_path / f"{name}.npz", members) for name, (members, _) in cases.items()]
    outcomes = H.load_in_child(paths, memory_mb=1024)
    for (name, (_, pattern)), path, (outcome, message) in zip(cases.items(), paths, outcomes):
        assert re.search(pattern, f"{outcome} {message}" if outcome == "ok" else message), (name, outcome, message)
        if outcome != "ok":
            assert outcome == "ModelFileError" and message.startswith(str(path)), (name, outcome, message)


def zlib_raw(data: bytes) -> bytes:
    import zlib

    c = zlib.compressobj(6, zlib.DEFLATED, -15)
    return c.compress(data) + c.flush()


def test_a_136_byte_npy_declaring_10_12_values_is_refused_before_allocating(tmp_path):
    path = tmp_path / "flame_dynamic_embedding.npy"
    path.write_bytes(_npy_header((10**12,)))
    assert len(path.read_bytes()) <= 136
    ((outcome, message),) = H.load_in_child([path])
    assert outcome == "ModelFileError" and "declares 1,000,000,000,000 elements" in message, message


def test_a_sparse_matrix_declaring_10_6_by_10_6_is_refused(tmp_path):
    import scipy.sparse as sp

    m = sp.csc_matrix(
        (np.ones(1), np.zeros(1, dtype=np.int32), np.r_[0, np.ones(10**6, dtype=np.int32)]), shape=(10**6, 10**6)
    )
    path = tmp_path / "SMPL_sparse.pkl"
    path.write_bytes(H.dumps({"J_regressor": m}))
    ((outcome, message),) = H.load_in_child([path])
    assert outcome == "ModelFileError" and "declares 1,000,000,000,000 elements" in message, message


def test_fifos_and_devices_are_refused_without_blocking(tmp_path):
    fifo = tmp_path / "SMPL_NEUTRAL.pkl"
    os.mkfifo(fifo)
    outcomes = H.load_in_child([fifo, "/dev/zero", tmp_path], timeout=60)
    assert outcomes[0][0] == "ModelFileError" and "is not a regular file (a FIFO)" in outcomes[0][1]
    assert outcomes[1][0] == "ModelFileError" and "is not a regular file (a character device)" in outcomes[1][1]
    assert outcomes[2][0] == "ModelFileError" and "is a directory" in outcomes[2][1]


def test_budgets_never_refuse_the_real_size_fakes(fake_models):
    """Every fake official file (real sizes: SMPL-X .npz 234 MB, SMPL .pkl 39-87 MB) and the open
    model load in a child limited to 3 GiB of address space."""
    keys = [
        "smplx_neutral_npz",
        "smplx_neutral_pkl",
        "smpl_neutral_pkl",
        "smplh_female_npz",
        "official_flame_generic_pkl",
    ]
    outcomes = H.load_in_child([fake_models[k] for k in keys] + [OPEN_MODEL_PATH], memory_mb=3072, timeout=300)
    assert [o[0] for o in outcomes] == ["ok"] * len(outcomes), outcomes
    assert [o[1] for o in outcomes] == ["smplx", "smplx", "smpl", "smplh", "flame", "open"]


@pytest.mark.parametrize("size", [0, 1, 100])
def test_load_budget_scales_with_the_file(size):
    from smplcore.io.budgets import FLOOR_BYTES, LoadBudget

    budget = LoadBudget("x", size)
    assert budget.limit == FLOOR_BYTES + 8 * size
    budget.charge(budget.limit, "all of it")
    with pytest.raises(Exception, match=r"x: one more byte would need 1 bytes"):
        budget.charge(1, "one more byte")


def test_npz_members_are_read_only_when_used(fake_models, tmp_path):
    """A damaged member that is never asked for does not stop the load (members are read lazily)."""
    from smplcore.io import load_model

    members = _mano_npz_members(fake_models) + [{"name": "not_needed.npy", "data": b"\x93NUMPY garbage"}]
    path = H.write_zip(tmp_path / "MANO_RIGHT.npz", members)
    with pytest.warns(UserWarning, match="not_needed"):
        data = load_model(path)
    assert data.model_type == "mano" and data.v_template.shape == (778, 3)


def test_read_array_file_reads_plain_arrays_and_refuses_the_rest(tmp_path):
    from smplcore.errors import ModelFileError
    from smplcore.io.containers import read_array_file

    good = tmp_path / "kid.npy"
    np.save(good, np.arange(6.0).reshape(2, 3))
    assert read_array_file(good).tolist() == [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]]
    huge = tmp_path / "huge.npy"
    huge.write_bytes(_npy_header((10**12,)))
    with pytest.raises(ModelFileError, match=r"huge\.npy: \.npy header: shape \(1000000000000,\) declares"):
        read_array_file(huge)
    pickled = tmp_path / "dict.npy"
    np.save(pickled, np.array({"a": 1}, dtype=object), allow_pickle=True)
    with pytest.raises(ModelFileError, match=r"expected a numeric array, found dtype object"):
        read_array_file(pickled)
    fifo = tmp_path / "fifo.npy"
    os.mkfifo(fifo)
    with pytest.raises(ModelFileError, match=r"not a regular file \(a FIFO\)"):
        read_array_file(fifo)
