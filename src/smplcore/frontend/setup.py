"""A model with its options applied: :class:`ModelSetup` turns a :class:`ModelData` and smplx's
constructor options (``num_betas``, ``use_pca``, ``flat_hand_mean``, ``use_face_contour``, ...) into
plain NumPy constants, the same for both front ends.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.engine import body as engine
from smplcore.engine.backend import for_cache, index, namespace
from smplcore.errors import ModelFileError, ShapeError, warn
from smplcore.family import names
from smplcore.family.specs import FamilySpec, extra_joint_vertex_ids, get_spec
from smplcore.io.model_data import ModelData

_warned: set[tuple[str, str]] = set()

#: smplx's constructor options that set up a model (with their defaults), for both front ends.
SETUP_OPTIONS: dict[str, Any] = {
    "num_betas": 10,
    "num_expression_coeffs": 10,
    "use_pca": True,
    "num_pca_comps": 6,
    "flat_hand_mean": False,
    "use_face_contour": False,
    "use_hands": True,
    "use_feet_keypoints": True,
    "vertex_ids": None,
    "age": "adult",
    "kid_template_path": "",
    "v_template": None,
    "joint_regressors": None,
    "dmpl_path": None,
    "skinning": "lbs",
}


def hand_options_from_file(data: ModelData, given: Any) -> dict[str, Any]:
    """``use_pca`` / ``flat_hand_mean`` for a file without hand PCA and mean hand pose (AMASS's SMPL+H / SMPL-X
    ``.npz``), when the caller gave neither: axis-angle hands (``use_pca=False``; smplx's default, True,
    cannot be read from such a file) with a flat mean (its hand poses are absolute). Otherwise nothing: the
    options given, or smplx's defaults, apply (``use_pca=True`` on such a file is still a clear error)."""
    spec = get_spec(data.model_type)
    if not spec.hand_blocks or spec.model_type == "mano" or "use_pca" in given or "flat_hand_mean" in given:
        return {}
    sides = ("left", "right")
    if all(getattr(data, f"hands_components_{s}", None) is None and getattr(data, f"hands_mean_{s}", None) is None
           for s in sides):  # fmt: skip
        return {"use_pca": False, "flat_hand_mean": True}
    return {}


#: The skinning methods of the ``skinning`` option: linear blend and dual-quaternion skinning.
SKINNING_METHODS = ("lbs", "dqs")


def warn_once(owner: str, message: str, key: str | None = None) -> None:
    """Warn with ``message`` once per ``(owner, key)`` in this process."""
    token = (owner, key or message)
    if token not in _warned:
        _warned.add(token)
        warn(message)


@dataclass
class ModelSetup:
    """A model with its options applied. All arrays are NumPy; nothing here depends on torch.

    Attributes
    ----------
    spec, data : the family spec and the file's arrays.
    num_betas, num_expression_coeffs : coefficients the model takes (after capping to the file).
    shapedirs : (V, 3, num_betas [+1 with a kid template]) shape basis.
    exprdirs : (V, 3, num_expression_coeffs) expression basis (empty for models without one).
    hand_components : PCA basis (C, 45) per hand block, only for blocks given as PCA coefficients.
    pose_mean : (3 J,) axis-angle added to the full pose (the mean hand pose unless flat).
    extra_joint_ids / extra_joint_names : vertices appended to the joints.
    use_face_contour : append the 17 dynamic contour landmarks.
    dmpldirs : (V, 3, num_dmpls) DMPL soft-tissue blend shapes (``dmpl_path``), or None.
    skinning : ``"lbs"`` (linear blend skinning, the models' own) or ``"dqs"`` (dual-quaternion skinning).
    """

    spec: FamilySpec
    data: ModelData
    num_betas: int
    num_expression_coeffs: int
    shapedirs: np.ndarray
    exprdirs: np.ndarray
    use_pca: bool
    num_pca_comps: int
    flat_hand_mean: bool
    hand_components: dict[str, np.ndarray]
    hand_means: dict[str, np.ndarray]
    pose_mean: np.ndarray
    extra_joint_ids: list[int]
    extra_joint_names: list[str]
    use_face_contour: bool
    neck_chain: list[int] = field(default_factory=list)
    # built in __post_init__ when not given, so always set afterwards
    keypoints: Keypoints = None  # type: ignore[assignment]
    regressor: Any = None  # smplcore.keypoints.Regressor of the joint_regressors option, or None
    dmpldirs: np.ndarray | None = None
    skinning: str = "lbs"
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def has_pose_mean(self) -> bool:
        """Whether a mean pose is added to the full pose (decided once, at construction)."""
        return self._cache["has_pose_mean"]

    def const(self, name: str, array: np.ndarray | None, like: Any) -> Any:
        """``array`` in the namespace, dtype (for floats) and device of ``like``, converted once."""
        key = (name, type(like).__module__, str(like.dtype), str(getattr(like, "device", "cpu")))
        value = self._cache.get(key)
        if value is None:
            if array is None:
                raise ModelFileError(self.data.source, f"the model has no {name} array", key=name)
            with for_cache():
                value = index(array, like) if np.asarray(array).dtype.kind in "iu" else _const(array, like)
            self._cache[key] = value
        return value

    def __post_init__(self) -> None:
        self._cache["has_pose_mean"] = bool(np.any(self.pose_mean))
        # plain Python values the forward reads (traceable by torch.compile, unlike NumPy arrays)
        self._cache["pca_blocks"] = frozenset(self.hand_components)
        self._cache["pca_widths"] = {k: int(v.shape[0]) for k, v in self.hand_components.items()}
        if self.keypoints is None:
            self.keypoints = Keypoints.build(
                self.data, self.extra_joint_ids, self.spec.landmarks, self.use_face_contour
            )

    @classmethod
    def build(
        cls,
        data: ModelData,
        *,
        num_betas: int = 10,
        num_expression_coeffs: int = 10,
        use_pca: bool = True,
        num_pca_comps: int = 6,
        flat_hand_mean: bool = False,
        use_face_contour: bool = False,
        use_hands: bool = True,
        use_feet_keypoints: bool = True,
        vertex_ids: dict | None = None,
        age: str | float = "adult",
        kid_template_path: str | Path | None = None,
        v_template: np.ndarray | None = None,
        joint_regressors: Any = None,
        dmpl_path: str | Path | None = None,
        skinning: str = "lbs",
        owner: str = "",
    ) -> ModelSetup:
        spec = get_spec(data.model_type)
        check_skinning(skinning)
        owner = owner or spec.display_name
        _check_count("num_betas", num_betas)
        if num_betas > data.num_betas:
            warn_once(
                owner,
                f"{owner}: num_betas={num_betas} asked, but {data.source} holds {data.num_betas} "
                f"shape components; using {data.num_betas}",
                key=f"betas{num_betas}-{data.source}",
            )
            num_betas = data.num_betas
        shapedirs = np.asarray(data.shapedirs[:, :, :num_betas])
        if isinstance(age, str):
            if age == "kid":  # the kid offset is measured from the file's template, before a custom one (as smplx)
                shapedirs, num_betas = _with_kid_component(data, shapedirs, kid_template_path), num_betas + 1
            elif age != "adult":
                raise ValueError(f"age: expected 'adult', 'kid' or years (the open model), got {age!r}")
        if v_template is not None:
            v_template = template_array(v_template)
            if v_template.shape != data.v_template.shape:
                per_sample = v_template.ndim == 3 and v_template.shape[1:] == data.v_template.shape
                raise ShapeError(
                    f"v_template: expected shape {data.v_template.shape}, got {v_template.shape}"
                    + (
                        "; one template per body (B, V, 3) is taken by the torch classes "
                        "(smplcore.create(..., v_template=templates, batch_size=B)), as in smplx"
                        if per_sample
                        else ""
                    )
                )
            data = data.replace(v_template=v_template)
        if not isinstance(age, str):  # years: the open model's age axis
            from smplcore.io.open_ages import at_age

            data, shapedirs = at_age(data, age, shapedirs)

        exprdirs = np.zeros((data.num_vertices, 3, 0))
        if spec.has_expression:
            _check_count("num_expression_coeffs", num_expression_coeffs)
            held = data.num_expression_coeffs
            if num_expression_coeffs > held:
                warn_once(
                    owner,
                    f"{owner}: num_expression_coeffs={num_expression_coeffs} asked, but {data.source} "
                    f"holds {held}; using {held}",
                    key=f"expr{num_expression_coeffs}-{data.source}",
                )
                num_expression_coeffs = held
            assert data.exprdirs is not None  # held > 0: the file has expression blend shapes
            exprdirs = np.asarray(data.exprdirs[:, :, :num_expression_coeffs])
        else:
            num_expression_coeffs = 0

        if spec.model_type == "mano" and num_pca_comps == 45:
            use_pca = False  # as smplx: 45 components are the full space, given as axis-angle
        hand_components, hand_means = {}, {}
        for block in spec.hand_blocks:
            side = data.gender if block.hand == "self" else block.hand
            comps = getattr(data, f"hands_components_{side}")
            mean = getattr(data, f"hands_mean_{side}")
            if use_pca:
                if comps is None:
                    raise ModelFileError(
                        data.source,
                        f"use_pca=True needs the {side} hand's PCA components, which "
                        "this file does not have; pass use_pca=False",
                        key="hands_components",
                    )
                if not 1 <= num_pca_comps <= comps.shape[0]:
                    raise ValueError(f"num_pca_comps: expected 1..{comps.shape[0]}, got {num_pca_comps}")
                hand_components[block.name] = np.asarray(comps[:num_pca_comps])
            if mean is None and not flat_hand_mean:
                warn_once(
                    owner,
                    f"{owner}: {data.source} has no mean hand pose; using a flat hand mean",
                    key=f"nomean-{data.source}",
                )
            hand_means[block.name] = np.zeros(45) if (flat_hand_mean or mean is None) else np.asarray(mean)
        offsets = spec.block_offsets()
        pose_mean = np.zeros((spec.num_joints, 3))
        for name, mean in hand_means.items():
            start, stop = offsets[name]
            pose_mean[start:stop] = mean.reshape(-1, 3)

        extra_names: list[str] = []
        extra_ids: list[int] = []
        if spec.extra_joints:
            ids = (
                vertex_ids
                or spec.vertex_ids
                or {names.EXTRA_JOINT_KEYS[n]: i for n, i in zip(data.extra_joint_names, data.extra_joint_vertex_ids)}
            )
            if ids:
                extra_names, extra_ids = extra_joint_vertex_ids(ids, use_hands, use_feet_keypoints)

        if use_face_contour and (not spec.landmarks or data.dynamic_lmk_faces_idx is None):
            raise ModelFileError(
                data.source,
                f"use_face_contour=True needs the dynamic face contour embedding, "
                f"which this {spec.display_name} model does not have",
                key="dynamic_lmk_faces_idx",
            )
        if spec.landmarks and data.lmk_faces_idx is None:
            where = "flame_static_embedding.pkl next to the model file" if spec.model_type == "flame" else "the file"
            raise ModelFileError(
                data.source, f"{spec.display_name} needs static landmark embeddings ({where})", key="lmk_faces_idx"
            )
        neck_chain = []
        if use_face_contour and spec.neck_index is not None:  # the contour's models have a neck joint
            neck_chain = engine.KinematicTree.from_parents(data.parents).chain_to_root(spec.neck_index)
        return cls(
            spec,
            data,
            num_betas,
            num_expression_coeffs,
            shapedirs,
            exprdirs,
            use_pca,
            num_pca_comps,
            flat_hand_mean,
            hand_components,
            hand_means,
            pose_mean.reshape(-1),
            extra_ids,
            extra_names,
            use_face_contour,
            neck_chain,
            regressor=_regressor(joint_regressors, data),
            dmpldirs=_dmpl(dmpl_path, data),
            skinning=skinning,
        )

    @property
    def num_dmpls(self) -> int:
        """DMPL coefficients the model takes (0 without ``dmpl_path``)."""
        return 0 if self.dmpldirs is None else int(self.dmpldirs.shape[-1])

    def blend_dirs(self) -> np.ndarray:
        """(V, 3, K) every coefficient's blend shape, in the order of the forward's coefficients:
        shape, then expression, then DMPL."""
        parts = [self.shapedirs, self.exprdirs] + ([] if self.dmpldirs is None else [self.dmpldirs])
        return np.concatenate(parts, axis=-1)

    def body_arrays(self, convert=np.asarray) -> engine.BodyArrays:
        """The engine's arrays (shape, expression and DMPL bases concatenated once, here)."""
        d = self.data
        dirs = self.blend_dirs()
        return engine.BodyArrays.build(
            d.v_template, dirs, d.J_regressor, d.posedirs, d.weights, d.parents, convert=convert
        )

    @property
    def output_joint_names(self) -> list[str]:
        """Names of the output joints, in order."""
        out = list(self.spec.joint_names if self.data.joint_names is None else self.data.joint_names)
        out += self.extra_joint_names
        if self.spec.landmarks:
            out += list(names.FACE_LANDMARKS[: len(self.keypoints.corners)])  # one face per landmark
            if self.use_face_contour:
                out += list(names.FACE_CONTOUR)
        if self.regressor is not None:
            out += list(self.regressor.names)
        return out

    def pose_width(self, block_name: str) -> int:
        """Values per body of a pose block in axis-angle mode (PCA coefficients for PCA hands)."""
        widths = self._cache["pca_widths"]
        return widths[block_name] if block_name in widths else 3 * self.spec.block(block_name).num_joints

    @property
    def pca_blocks(self) -> frozenset[str]:
        """The pose blocks given as hand-PCA coefficients."""
        return self._cache["pca_blocks"]


def check_skinning(skinning: Any) -> str:
    """``skinning`` if it names a skinning method, else a ValueError naming the option and the choices."""
    if skinning not in SKINNING_METHODS:
        raise ValueError(
            f"skinning: expected 'lbs' (linear blend skinning) or 'dqs' (dual-quaternion skinning), got {skinning!r}"
        )
    return skinning


def template_array(value: Any) -> np.ndarray:
    """The ``v_template`` option as a finite float64 array; errors name the option."""
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"v_template: expected a (V, 3) array of numbers, got {type(value).__name__}") from exc
    if not np.all(np.isfinite(array)):
        raise ValueError("v_template: holds NaN or infinite values")
    return array


def _regressor(joint_regressors: Any, data: ModelData) -> Any:
    """The ``joint_regressors`` option (convention -> regressor file, ``Regressor`` or ``"open"``) as one
    stacked :class:`smplcore.keypoints.Regressor` checked against the model's vertex count, or None."""
    if joint_regressors is None or (isinstance(joint_regressors, (dict, list, tuple, str)) and not joint_regressors):
        return None
    from smplcore.keypoints import load_regressors

    if not isinstance(joint_regressors, (dict, str, Path)) and not hasattr(joint_regressors, "matrix"):
        raise TypeError(
            "joint_regressors: expected {convention: regressor file or Regressor}, a Regressor or 'open', got "
            f"{type(joint_regressors).__name__}"
        )

    return load_regressors(joint_regressors, num_vertices=data.num_vertices)


def _dmpl(dmpl_path: str | Path | None, data: ModelData) -> np.ndarray | None:
    """The ``dmpl_path`` option: (V, 3, n) DMPL blend shapes checked against the model's vertices, or None."""
    if dmpl_path is None or (isinstance(dmpl_path, str) and dmpl_path == ""):
        return None
    if not isinstance(dmpl_path, (str, Path)):
        raise TypeError(f"dmpl_path: expected the path of a DMPL .npz file, got {type(dmpl_path).__name__}")
    from smplcore.io.dmpl import load_dmpl

    return load_dmpl(dmpl_path, num_vertices=data.num_vertices)


def _check_count(name: str, value: int) -> None:
    if not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{name}: expected a non-negative integer, got {value!r}")


def _with_kid_component(data: ModelData, shapedirs: np.ndarray, kid_template_path) -> np.ndarray:
    """Append the kid template's offset from the adult template as one more shape component."""
    if not kid_template_path:
        raise ValueError("kid_template_path: age='kid' needs the path of the kid template (.npy)")
    from smplcore.io.containers import read_array_file

    path = Path(kid_template_path)
    kid = read_array_file(path)
    if kid.shape != data.v_template.shape:
        raise ModelFileError(path, f"expected shape {data.v_template.shape}, found {kid.shape}")
    kid = kid - kid.mean(axis=0)
    return np.concatenate([shapedirs, (kid - data.v_template)[:, :, None]], axis=2)


def _const(array: np.ndarray, like: Any) -> Any:
    """A NumPy constant in the namespace, dtype and device of ``like``."""
    if namespace(like) is np:
        return np.asarray(array, dtype=like.dtype)
    import torch

    return torch.tensor(np.asarray(array), dtype=like.dtype, device=like.device)


@dataclass(frozen=True)
class Keypoints:
    """Vertices that the extra joints and landmarks read, numbered globally and within their subset.

    ``corners``/``contour_corners`` hold the three vertices of each landmark's face: (L, 3) and
    (79, 17, 3). The ``local_*`` fields number them within ``ids``, so that the joints-only path
    poses just those vertices.
    """

    ids: np.ndarray
    extra: np.ndarray
    corners: np.ndarray
    contour_corners: np.ndarray
    local_extra: np.ndarray
    local_corners: np.ndarray
    local_contour_corners: np.ndarray

    @classmethod
    def build(cls, data: ModelData, extra_ids: list[int], landmarks: bool, contour: bool) -> Keypoints:
        extra = np.asarray(extra_ids, dtype=np.int64)
        corners = data.faces[data.lmk_faces_idx] if landmarks else np.zeros((0, 3), np.int64)
        contour_corners = data.faces[data.dynamic_lmk_faces_idx] if contour else np.zeros((79, 0, 3), np.int64)
        ids, inverse = np.unique(np.concatenate([extra, corners.ravel(), contour_corners.ravel()]), return_inverse=True)
        n1, n2 = extra.size, extra.size + corners.size
        return cls(
            ids,
            extra,
            corners,
            contour_corners,
            inverse[:n1],
            inverse[n1:n2].reshape(corners.shape),
            inverse[n2:].reshape(contour_corners.shape),
        )
