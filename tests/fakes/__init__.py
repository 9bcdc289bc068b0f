"""Structurally exact fake *official* body-model files, built from seeded random data.

The official SMPL / SMPL+H / SMPL-X / MANO / FLAME files cannot be downloaded in tests, so this
package writes stand-ins with the real file names, key names, shapes, dtypes and container
formats:

* legacy pickles (SMPL, MANO, FLAME, SMPL-X ``.pkl``, the raw SMPL+H ``.pkl``) are written the
  way Python 2 wrote them: pickle protocol 2, byte strings (dict keys, array data) as Python 2
  ``str`` opcodes (``BINSTRING`` / ``SHORT_BINSTRING``, so loading needs ``encoding="latin1"``
  exactly like the real files), and the legacy global names ``numpy.core.multiarray`` and
  ``scipy.sparse.csc`` instead of today's ``numpy._core.multiarray`` / ``scipy.sparse._csc``;
* ``shapedirs`` is a chumpy ``Ch`` where the official file has one, ``J_regressor`` a
  ``scipy.sparse.csc_matrix`` where the official file has one;
* ``.npz`` files are plain ``numpy.savez`` archives (object arrays where the real ones have them).

The contents are random but *valid*: a rough T-pose skeleton at human scale (metres, y up,
z forward, +x = the body's left), vertices scattered around its bones (real vertex counts, so the
fixed vertex ids smplx uses for extra joints exist; those ids are moved onto plausible spots --
nose, eyes, ears, toes, heels, fingertips), skinning weights on 1-4 nearby joints summing to 1,
joint regressors with non-negative rows summing to 1 over 10-40 vertices near each joint, closed
triangle lists using every vertex, small blend shapes of realistic magnitude, valid landmark
faces with positive barycentric coordinates.

Everything is deterministic in ``seed``; the same ``(model, gender, seed)`` gives the same numbers
whatever the container (``.pkl`` vs ``.npz``) or file name, so readers of both can be compared.
Only numpy and scipy are needed at import time; chumpy is imported when a ``Ch`` is written.

Facts about the real files that could not be checked here (only their structure as read by
smplx 0.1.28 is certain) and were chosen as follows:

* dtypes: ``f`` uint32 and ``kintree_table`` int64 with ``4294967295`` as the root's parent in
  every file; landmark face indices int64 in SMPL-X, uint32 in the FLAME embeddings; all float
  data float64 (including the big SMPL-X ``.npz``);
* the SMPL-X files have no ``J``; their ``.npz`` has the stray ``allow_pickle`` entry;
  ``joint2num``/``part2num`` contents are made up (names -> ints);
* old scipy's ``csc_matrix`` pickled state is taken to be today's (``_shape``, ``maxprint``,
  ``indices``, ``indptr``, ``data``); chumpy ``Ch`` state is whatever chumpy-fixed writes;
* ``pose_training_info`` contents are made up; the SMPL+H / AMASS ``.npz`` string entries
  (``bs_style``, ``bs_type``) are 0-d unicode arrays;
* the FLAME dynamic embedding holds ndarrays (the real one may hold lists of arrays);
* MANO_LEFT's faces are taken to be the right hand's with reversed winding.

Modules: ``sizes`` (real sizes, vertex ids), ``pickles`` (legacy containers), ``skeletons`` and
``meshes`` (the random-but-valid geometry), ``body`` (SMPL, SMPL+H, SMPL's UV ``.obj``),
``smplx_model`` (SMPL-X, kid templates), ``mano_flame`` (MANO, FLAME), ``tree`` (``write_all``).
Everything is re-exported here, so ``import fakes`` / ``from fakes import write_smpl`` work.

Public API (all return :class:`pathlib.Path`):

``write_smpl``, ``write_smplh``, ``write_smplx``, ``write_kid_template``,
``write_smplx_kid_template``, ``write_mano``, ``write_flame``, ``write_flame_landmarks``,
``write_all`` (returns a dict of paths).
"""

from __future__ import annotations

from .body import _smpl_arrays, _smplh_arrays, write_smpl, write_smpl_uv_obj, write_smplh
from .mano_flame import _flame_arrays, _mano_left, _mano_right, write_flame, write_flame_landmarks, write_mano
from .meshes import _norm_gender, _seam_uvs
from .pickles import _ch, _dense, _LegacyPickler, _npz, _object0, _save_legacy_npy_object, dump_legacy_pickle
from .sizes import (
    _MANO_VERTEX_IDS,
    _SMPLH_VERTEX_IDS,
    _SMPLX_VERTEX_IDS,
    FLAME_FACES,
    FLAME_VERTS,
    HAND_COEFF_ROWS,
    MANO_FACES,
    MANO_VERTS,
    ROOT_PARENT,
    SMPL_FACES,
    SMPL_UVS,
    SMPL_VERTS,
    SMPLX_FACES,
    SMPLX_UVS,
    SMPLX_VERTS,
)
from .smplx_model import _SMPLX_JOINT_NAMES, _smplx_arrays, write_kid_template, write_smplx, write_smplx_kid_template
from .tree import _link, write_all

__all__ = [
    "FLAME_FACES",
    "FLAME_VERTS",
    "HAND_COEFF_ROWS",
    "MANO_FACES",
    "MANO_VERTS",
    "ROOT_PARENT",
    "SMPLX_FACES",
    "SMPLX_UVS",
    "SMPLX_VERTS",
    "SMPL_FACES",
    "SMPL_UVS",
    "SMPL_VERTS",
    "dump_legacy_pickle",
    "write_all",
    "write_flame",
    "write_flame_landmarks",
    "write_kid_template",
    "write_mano",
    "write_smpl",
    "write_smpl_uv_obj",
    "write_smplh",
    "write_smplx",
    "write_smplx_kid_template",
]

# Helpers other test modules (hostile_files.py, bench/fixtures.py, fakes_<topic>.py) build on.
_HELPERS = (
    _LegacyPickler,
    _ch,
    _dense,
    _flame_arrays,
    _link,
    _mano_left,
    _mano_right,
    _norm_gender,
    _npz,
    _object0,
    _save_legacy_npy_object,
    _seam_uvs,
    _smpl_arrays,
    _smplh_arrays,
    _smplx_arrays,
    _MANO_VERTEX_IDS,
    _SMPLH_VERTEX_IDS,
    _SMPLX_VERTEX_IDS,
    _SMPLX_JOINT_NAMES,
)
