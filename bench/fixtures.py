"""Model files for the benchmark: fake official files of real size, laid out for every library.

* smplx / smplcore read the smplx-style tree ``<root>/{smpl,smplh,smplx}/`` written by
  ``tests/fakes.py`` (SMPL v1.1 ``.pkl`` with 300 betas, the merged SMPL+H ``.pkl``, the SMPL-X v1.1
  ``.npz`` with 300 + 100 components);
* body-models takes the same file by path;
* smplfitter looks for ``<model_root>/basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl``,
  ``SMPLX_NEUTRAL.npz`` or ``SMPLH_{male,female}.pkl`` (SMPL+H has no neutral in its name map),
  plus a ``kid_template.npy``: hard links to the very same files (the SMPL+H neutral file under the
  ``male`` name) and an all-zero kid template, smplfitter's own placeholder for "no kid template";
* the open model (``smplcore/data/open_model.npz``, smplcore's own format) is also written out in
  the SMPL layout (zero ``posedirs``, since it has no pose correctives) so that the other libraries
  can run the same mesh and skeleton.
"""

from __future__ import annotations

import os
import pickle
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OPEN_MODEL = REPO / "src" / "smplcore" / "data" / "open_model.npz"
FORMAT = "2"  # bump when the layout below changes


@dataclass(frozen=True)
class ModelFiles:
    """Where each library finds one model."""

    key: str  # smpl, smplh, smplx, open
    smplx_root: Path  # for smplx.create(root, model_type=smplx_type, ext=ext)
    smplx_type: str
    ext: str
    file: Path  # the model file itself (smplcore.BodyModel, body-models)
    smplfitter_root: Path
    smplfitter_name: str
    smplfitter_gender: str


def default_cache() -> Path:
    return Path(os.environ.get("SMPLCORE_BENCH_CACHE", Path(tempfile.gettempdir()) / "smplcore-bench-files"))


def _link(src: Path, dst: Path) -> None:
    """Same bytes under another name (the fakes' hard-link helper)."""
    _fakes()._link(src, dst)


def _kid_placeholder(root: Path, num_verts: int) -> None:
    np.save(root / "kid_template.npy", np.zeros((num_verts, 3)))


def _fakes():
    tests = str(REPO / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    import fakes

    return fakes


def open_model_available() -> bool:
    return OPEN_MODEL.is_file()


def prepare(key: str, cache: Path | None = None) -> ModelFiles:
    """Write (once) and return the files of model ``key``."""
    cache = Path(cache or default_cache()) / f"v{FORMAT}"
    stamp = cache / f"{key}.done"
    if key == "open":
        # Rewritten whenever the packaged model changes.
        stamp = cache / f"open-{int(OPEN_MODEL.stat().st_mtime_ns)}-{OPEN_MODEL.stat().st_size}.done"
    files = _layout(key, cache)
    if stamp.exists():
        return files
    if key == "smpl":
        src = _fakes().write_smpl(cache / "tree" / "smpl", "neutral", "1.1", "pkl")
        _link(src, files.smplfitter_root / files.smplfitter_name)
        _kid_placeholder(files.smplfitter_root, 6890)
    elif key == "smplh":
        src = _fakes().write_smplh(cache / "tree" / "smplh", "neutral", "pkl")
        _link(src, files.smplfitter_root / files.smplfitter_name)
        _kid_placeholder(files.smplfitter_root, 6890)
    elif key == "smplx":
        src = _fakes().write_smplx(cache / "tree" / "smplx", "neutral", "npz", "1.1")
        _link(src, files.smplfitter_root / files.smplfitter_name)
        _kid_placeholder(files.smplfitter_root, 10475)
    elif key == "open":
        _write_open_as_smpl(files)
    else:
        raise ValueError(f"unknown model {key!r}")
    for old in cache.glob(f"{key}*.done"):
        old.unlink()
    stamp.touch()
    return files


def _layout(key: str, cache: Path) -> ModelFiles:
    if key == "smpl":
        return ModelFiles(
            key,
            cache / "tree",
            "smpl",
            "pkl",
            cache / "tree" / "smpl" / "SMPL_NEUTRAL.pkl",
            cache / "smplfitter" / "smpl",
            "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl",
            "neutral",
        )
    if key == "smplh":
        return ModelFiles(
            key,
            cache / "tree",
            "smplh",
            "pkl",
            cache / "tree" / "smplh" / "SMPLH_NEUTRAL.pkl",
            cache / "smplfitter" / "smplh",
            "SMPLH_male.pkl",
            "male",
        )
    if key == "smplx":
        return ModelFiles(
            key,
            cache / "tree",
            "smplx",
            "npz",
            cache / "tree" / "smplx" / "SMPLX_NEUTRAL.npz",
            cache / "smplfitter" / "smplx",
            "SMPLX_NEUTRAL.npz",
            "neutral",
        )
    if key == "open":
        return ModelFiles(
            key,
            cache / "open_tree",
            "smpl",
            "pkl",
            cache / "open_tree" / "smpl" / "SMPL_NEUTRAL.pkl",
            cache / "smplfitter" / "open",
            "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl",
            "neutral",
        )
    raise ValueError(f"unknown model {key!r}")


def _write_open_as_smpl(files: ModelFiles) -> None:
    """The packaged open model in the official SMPL layout (posedirs all zero)."""
    d = np.load(OPEN_MODEL, allow_pickle=False)
    v = np.asarray(d["v_template"], np.float64)
    parents = np.asarray(d["parents"], np.int64)
    num_joints = parents.shape[0]
    kintree = np.stack([np.where(parents < 0, 4294967295, parents), np.arange(num_joints)]).astype(np.int64)
    arrays = {
        "v_template": v,
        "f": np.asarray(d["faces"], np.uint32),
        "shapedirs": np.asarray(d["shapedirs"], np.float64),
        "posedirs": np.zeros((v.shape[0], 3, 9 * (num_joints - 1))),
        "J_regressor": np.asarray(d["J_regressor"], np.float64),
        "weights": np.asarray(d["weights"], np.float64),
        "kintree_table": kintree,
    }
    files.file.parent.mkdir(parents=True, exist_ok=True)
    with open(files.file, "wb") as fh:  # a plain pickle: smplx 0.1.28 reads SMPL only as .pkl
        pickle.dump(arrays, fh, protocol=4)
    _link(files.file, files.smplfitter_root / files.smplfitter_name)
    _kid_placeholder(files.smplfitter_root, v.shape[0])
