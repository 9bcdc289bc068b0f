"""The in-memory form of a body model file: plain, read-only NumPy arrays.

Every reader in :mod:`smplcore.io` produces a :class:`ModelData`; everything above ``io`` (engine,
front ends, export) reads only this. The same fields, under the same names, are the keys of
smplcore's own pickle-free ``.npz`` layout (see :func:`smplcore.io.save_npz`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

#: Model types known to the library. ``open`` is smplcore's CC0 body model in the SMPL layout.
MODEL_TYPES = ("smpl", "smplh", "smplx", "mano", "flame", "open")


@dataclass(frozen=True, eq=False)
class ModelData:
    """Arrays of one body model file.

    Shapes use ``V`` vertices, ``F`` faces, ``J`` joints, ``S`` shape and ``E`` expression
    components, ``P = 9 * (J - 1)`` pose-corrective features and ``L`` landmarks.

    Attributes
    ----------
    model_type : one of :data:`MODEL_TYPES`.
    gender : ``"neutral"``, ``"male"``, ``"female"`` (or ``"right"`` / ``"left"`` for MANO).
    v_template : (V, 3) rest-pose template.
    faces : (F, 3) int64 triangle vertex indices.
    shapedirs : (V, 3, S) shape blend shapes.
    posedirs : (V, 3, P) pose-corrective blend shapes, or None when the model has none.
    J_regressor : (J, V) joint regressor (dense).
    weights : (V, J) skinning weights, rows summing to 1.
    parents : (J,) int64 parent index per joint, -1 for the root.
    exprdirs : (V, 3, E) expression blend shapes (SMPL-X, FLAME), or None.
    hands_components_left, hands_components_right : (C, 45) hand-pose PCA bases, or None.
    hands_mean_left, hands_mean_right : (45,) mean hand poses, or None.
    lmk_faces_idx : (L,) int64 faces of the static landmarks, or None.
    lmk_bary_coords : (L, 3) barycentric coordinates of the static landmarks, or None.
    dynamic_lmk_faces_idx : (79, 17) int64 faces of the dynamic face contour, or None.
    dynamic_lmk_bary_coords : (79, 17, 3) barycentric coordinates of the contour, or None.
    joint_names : names of the J joints, or None.
    extra_joint_names, extra_joint_vertex_ids : named vertices used as extra joints (e.g. nose,
        toes, fingertips) when the file brings its own (the open model), else empty.
    vt : (T, 2) texture coordinates (OBJ convention, v up; T >= V because seams split UVs), or None.
    ft : (F, 3) int64 indices into ``vt``, corner for corner with ``faces``, or None.
    source : the file the data was read from (for messages), or a description.
    faces_dtype : the integer dtype of the file's faces (``faces`` itself is always int64).
    """

    model_type: str
    gender: str
    v_template: np.ndarray
    faces: np.ndarray
    shapedirs: np.ndarray
    posedirs: np.ndarray | None
    J_regressor: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    exprdirs: np.ndarray | None = None
    hands_components_left: np.ndarray | None = None
    hands_components_right: np.ndarray | None = None
    hands_mean_left: np.ndarray | None = None
    hands_mean_right: np.ndarray | None = None
    lmk_faces_idx: np.ndarray | None = None
    lmk_bary_coords: np.ndarray | None = None
    dynamic_lmk_faces_idx: np.ndarray | None = None
    dynamic_lmk_bary_coords: np.ndarray | None = None
    joint_names: tuple[str, ...] | None = None
    extra_joint_names: tuple[str, ...] = ()
    extra_joint_vertex_ids: tuple[int, ...] = ()
    vt: np.ndarray | None = None
    ft: np.ndarray | None = None
    source: str = field(default="<memory>")
    faces_dtype: str = "int64"

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray) and value.flags.writeable:
                view = value.view()
                view.flags.writeable = False
                object.__setattr__(self, f.name, view)

    @property
    def num_vertices(self) -> int:
        return int(self.v_template.shape[0])

    @property
    def num_joints(self) -> int:
        return int(self.parents.shape[0])

    @property
    def num_betas(self) -> int:
        return int(self.shapedirs.shape[-1])

    @property
    def num_expression_coeffs(self) -> int:
        return 0 if self.exprdirs is None else int(self.exprdirs.shape[-1])

    @property
    def has_uv(self) -> bool:
        """True when the model carries a UV map (``vt`` and ``ft``)."""
        return self.vt is not None and self.ft is not None

    def replace(self, **changes) -> ModelData:
        """A copy with some fields replaced (the data is frozen)."""
        return dataclasses.replace(self, **changes)
