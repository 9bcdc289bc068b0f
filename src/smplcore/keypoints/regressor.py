"""Extra joint regressors: (K, V) matrices that turn posed vertices into K named keypoints.

SPIN's ``J_regressor_h36m.npy``, ``J_regressor_extra.npy``, a seed's ``J_regressor_extra`` or
smplcore's own regressors for the open model (:func:`open_model_regressor`). Files are read without
running anything in them: ``.npy`` arrays directly, pickles (``.pkl``, object ``.npy``) through
smplcore's allow-list unpickler, ``.npz`` as arrays (a dense matrix, or scipy's ``save_npz`` layout).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError, ShapeError
from smplcore.io import MAX_ARRAY_ELEMENTS
from smplcore.keypoints.conventions import names as convention_names

_MATRIX_KEYS = ("J_regressor", "regressor", "matrix", "J_regressor_extra", "J_regressor_h36m", "weights")
OPEN_REGRESSORS_PATH = Path(__file__).resolve().parents[1] / "data" / "open_regressors.npz"


def _is_sparse(m: Any) -> bool:
    return hasattr(m, "tocsr") and hasattr(m, "nnz")


@dataclass(frozen=True, eq=False)
class Regressor:
    """K named keypoints as linear functions of a mesh's V vertices.

    Attributes
    ----------
    matrix : (K, V) dense ``np.ndarray`` or ``scipy.sparse`` CSR matrix.
    names : K point names (qualified as ``"convention:name"`` by :meth:`qualified_names`).
    convention : the convention the rows follow, or None.
    source : where it came from (a file path or a description).
    """

    matrix: Any
    names: tuple[str, ...]
    convention: str | None = None
    source: str = "<array>"
    _compact: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        shape = tuple(self.matrix.shape)
        if len(shape) != 2:
            raise ShapeError(f"matrix: expected shape (K, V), got {shape}")
        if len(self.names) != shape[0]:
            raise ShapeError(
                f"names: expected {shape[0]} names for a ({shape[0]}, {shape[1]}) regressor, got {len(self.names)}"
            )
        dense = np.asarray(self.matrix.toarray() if _is_sparse(self.matrix) else self.matrix, dtype=np.float64)
        if not np.all(np.isfinite(dense)):
            raise ShapeError(f"matrix: the regressor from {self.source} holds NaN or infinite weights")
        ids = np.flatnonzero(np.any(dense != 0, axis=0))
        object.__setattr__(self, "_compact", (ids, np.ascontiguousarray(dense[:, ids])))

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def load(
        cls,
        path: str | Path,
        *,
        convention: str | None = None,
        names: tuple[str, ...] | list[str] | None = None,
        num_vertices: int | None = None,
        key: str | None = None,
    ) -> Regressor:
        """Read a regressor from ``.npy``, ``.npz`` or ``.pkl`` (dense or scipy.sparse).

        Parameters
        ----------
        path : the file; its kind is told from its first bytes.
        convention : the convention of its rows (``"h36m17"``); gives the names.
        names : point names instead (default: ``names`` stored in the file, else ``"{stem}_{k}"``).
        num_vertices : the model's vertex count; a regressor with another V raises ModelFileError.
        key : the entry holding the matrix in an ``.npz`` or pickled dict (default: the only array,
            or one of ``J_regressor``, ``regressor``, ``matrix``, ...).

        Raises
        ------
        ModelFileError
            Missing, corrupt or unsafe file (a pickle naming anything but arrays and sparse
            matrices is refused before anything runs), no (K, V) matrix in it, a wrong vertex
            count, or names that do not match its rows.
        """
        path = Path(path)
        matrix, stored_names = _read_matrix(path, key)
        if num_vertices is not None and matrix.shape[1] != int(num_vertices):
            raise ModelFileError(
                path,
                f"the regressor has {matrix.shape[1]} columns but the model has {num_vertices} vertices; "
                "use a regressor made for this model's mesh",
                key=key,
            )
        if names is None and convention is not None:
            names = convention_names(convention)
        if names is None:
            names = stored_names or tuple(f"{path.stem}_{k}" for k in range(matrix.shape[0]))
        names = tuple(str(n) for n in names)
        if len(names) != matrix.shape[0]:
            what = f"convention {convention!r}" if convention else "names"
            raise ModelFileError(path, f"the regressor has {matrix.shape[0]} rows but {what} has {len(names)} points")
        return cls(matrix, names, None if convention is None else str(convention), str(path))

    # -- what it uses -------------------------------------------------------------------------
    @property
    def num_vertices(self) -> int:
        return int(self.matrix.shape[1])

    @property
    def vertex_ids(self) -> np.ndarray:
        """(n,) sorted ids of the vertices any row uses (the joints-only path needs just these)."""
        return self._compact[0]

    @property
    def weights(self) -> np.ndarray:
        """(K, n) float64 weights on :attr:`vertex_ids` (the matrix without its all-zero columns)."""
        return self._compact[1]

    def qualified_names(self) -> tuple[str, ...]:
        """Names as ``"convention:name"`` (plain names without a convention): unambiguous next to a model's
        own joints, and understood by :func:`smplcore.keypoints.convert`."""
        if self.convention is None:
            return self.names
        return tuple(n if ":" in n else f"{self.convention}:{n}" for n in self.names)

    def check(self, num_vertices: int, path: str | None = None) -> None:
        """Raise ModelFileError unless the regressor is for a mesh of ``num_vertices`` vertices."""
        if self.num_vertices != int(num_vertices):
            raise ModelFileError(
                path or self.source,
                f"the regressor has {self.num_vertices} columns but the model has {num_vertices} vertices",
            )

    # -- evaluation ---------------------------------------------------------------------------
    def apply(self, vertices: Any) -> Any:
        """Keypoints (..., K, 3) of ``vertices`` (..., V, 3), NumPy array or torch tensor (same dtype/device)."""
        shape = tuple(vertices.shape)
        if len(shape) < 2 or shape[-2] != self.num_vertices:
            raise ShapeError(f"vertices: expected shape (..., {self.num_vertices}, D), got {shape}")
        if type(vertices).__module__.split(".")[0] == "torch":
            import torch

            ids = torch.as_tensor(self.vertex_ids, dtype=torch.long, device=vertices.device)
            return self.apply_subset(vertices.index_select(-2, ids))
        return self.apply_subset(np.take(np.asarray(vertices), self.vertex_ids, axis=-2))

    def apply_subset(self, subset: Any) -> Any:
        """Keypoints (..., K, D) from ``subset`` (..., n, D): only the vertices :attr:`vertex_ids`, in that order.

        For the joints-only path: pose just these vertices, then call this.
        """
        shape = tuple(subset.shape)
        if len(shape) < 2 or shape[-2] != len(self.vertex_ids):
            raise ShapeError(f"subset: expected shape (..., {len(self.vertex_ids)}, D) (the vertex_ids), got {shape}")
        if type(subset).__module__.split(".")[0] == "torch":
            import torch

            w = torch.as_tensor(self.weights, dtype=subset.dtype, device=subset.device)
            return torch.matmul(w, subset)
        arr = np.asarray(subset)
        dtype = arr.dtype if arr.dtype.kind == "f" else np.float64
        return np.matmul(self.weights.astype(dtype, copy=False), arr.astype(dtype, copy=False))

    __call__ = apply


# -- reading --------------------------------------------------------------------------------------


def _read_matrix(path: Path, key: str | None) -> tuple[Any, tuple[str, ...] | None]:
    from smplcore.io import read_arrays

    value = read_arrays(path, "a regressor file (.npy, .npz or .pkl)")
    try:
        return _pick_matrix(path, value, key)
    except ModelFileError:
        raise
    except Exception as exc:  # noqa: BLE001 - a forged sparse layout, odd names, ...: a file error
        raise ModelFileError(path, f"unusable regressor ({type(exc).__name__}: {exc})", key=key) from None


def _pick_matrix(path: Path, value: Any, key: str | None) -> tuple[Any, tuple[str, ...] | None]:
    stored_names = None
    if isinstance(value, Mapping):  # a dict, or the loader's lazy .npz
        if "names" in value:
            stored_names = tuple(str(n) for n in np.asarray(value["names"]).ravel())
        if {"data", "indices", "indptr", "shape"} <= set(value):  # scipy.sparse.save_npz
            import scipy.sparse as sp

            fmt = np.asarray(value.get("format", b"csr")).item()
            fmt = fmt.decode() if isinstance(fmt, bytes) else str(fmt)
            cls = sp.csc_matrix if fmt == "csc" else sp.csr_matrix
            shape = tuple(int(s) for s in np.asarray(value["shape"]).ravel())
            matrix = cls((value["data"], value["indices"], value["indptr"]), shape=shape)
        else:
            candidates = [key] if key else [k for k in _MATRIX_KEYS if k in value]
            if not candidates:
                arrays = [k for k, v in value.items() if k != "names" and (_is_sparse(v) or np.ndim(v) == 2)]
                candidates = arrays if len(arrays) == 1 else []
            if not candidates or candidates[0] not in value:
                raise ModelFileError(
                    path,
                    f"no regressor matrix found among the keys {sorted(value)}; pass key= to name it",
                    key=key,
                )
            key = candidates[0]
            matrix = value[key]
    else:
        matrix = value
    if not _is_sparse(matrix):
        from smplcore.io import numeric_array

        matrix = numeric_array(path, matrix, key, kinds="biuf")
        if matrix.dtype.kind not in "fiu":
            raise ModelFileError(path, f"expected a numeric (K, V) matrix, found dtype {matrix.dtype}", key=key)
    if len(matrix.shape) != 2:
        raise ModelFileError(path, f"expected a (K, V) matrix, found shape {tuple(matrix.shape)}", key=key)
    if int(matrix.shape[0]) * int(matrix.shape[1]) > MAX_ARRAY_ELEMENTS:
        raise ModelFileError(
            path, f"a ({matrix.shape[0]}, {matrix.shape[1]}) regressor is larger than any body model needs", key=key
        )
    if _is_sparse(matrix):
        matrix = matrix.tocsr().astype(np.float64)
    else:
        matrix = matrix.astype(np.float64)
    return matrix, stored_names


def load_regressors(regressors: Any, num_vertices: int | None = None) -> Regressor:
    """Several regressors stacked into one, for a model option such as ``joint_regressors={"h36m17": path}``.

    Parameters
    ----------
    regressors : mapping convention -> a path, a :class:`Regressor`, or ``"open"`` for smplcore's own
        open-model regressor of that convention; keys that are no known convention name the points
        ``"{key}_{k}"`` (a Regressor value keeps its names).
    num_vertices : the model's vertex count; any regressor for another mesh raises ModelFileError.

    Returns
    -------
    Regressor whose rows are all the regressors' rows in the mapping's order, named by
    :meth:`Regressor.qualified_names` (``"h36m17:pelvis"``), so that they can be appended to a
    model's joints without clashing with its own names; ``vertex_ids`` is the union.
    """
    import scipy.sparse as sp

    from smplcore.keypoints.conventions import convention_key

    parts: list[Regressor] = []
    for key, value in dict(regressors).items():
        try:
            convention = convention_key(key)
        except ValueError:
            convention = None
        if isinstance(value, Regressor):
            reg = value
        elif isinstance(value, str) and value == "open":
            if convention is None:
                raise ValueError(f"joint_regressors[{key!r}]: 'open' needs a convention name as the key")
            reg = open_model_regressor(convention)
        else:
            reg = Regressor.load(value, convention=convention)
            if convention is None:
                reg = Regressor(reg.matrix, tuple(f"{key}_{k}" for k in range(reg.matrix.shape[0])), None, reg.source)
        if num_vertices is not None:
            reg.check(num_vertices)
        parts.append(reg)
    if not parts:
        raise ValueError("joint_regressors: expected at least one regressor")
    columns = {p.num_vertices for p in parts}
    if len(columns) > 1:
        raise ModelFileError(parts[0].source, f"the regressors are for meshes of different sizes {sorted(columns)}")
    matrix = sp.vstack([sp.csr_matrix(p.matrix) for p in parts], format="csr")
    names = tuple(n for p in parts for n in p.qualified_names())
    sources = "; ".join(p.source for p in parts)
    return Regressor(matrix, names, None, sources)


# -- the open model's own regressors --------------------------------------------------------------


def open_model_regressor(convention: str) -> Regressor:
    """smplcore's own regressor for the open model in ``convention`` (``coco17``, ``h36m17``, ``openpose25``).

    Built by ``tools/build_open_regressors.py`` from the open model's named vertices and its joint
    regressor; not Human3.6M's learned regressor or any official SMPL file (see docs/keypoints.md).
    """
    from smplcore.io import read_container
    from smplcore.keypoints.conventions import convention_key

    key = convention_key(convention)
    data = read_container(OPEN_REGRESSORS_PATH)
    available = sorted({k.split(".")[0] for k in data if k.endswith(".data")})
    if f"{key}.data" not in data:
        raise ValueError(f"convention: the open model ships regressors for {available}, not {convention!r}")
    import scipy.sparse as sp

    shape = tuple(int(s) for s in data[f"{key}.shape"])
    matrix = sp.csr_matrix((data[f"{key}.data"], data[f"{key}.indices"], data[f"{key}.indptr"]), shape=shape)
    return Regressor(matrix, convention_names(key), key, f"{OPEN_REGRESSORS_PATH}[{key}]")
