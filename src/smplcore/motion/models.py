"""The body model a motion file names, found in a folder, loaded once, and evaluated in batches.

A motion says its model type (SMPL+H, SMPL-X, ...) and its gender; :mod:`smplcore.io.locate` (the one
locator) finds the matching file in a model folder laid out either like smplx
(``models/smplh/SMPLH_FEMALE.npz``) or like AMASS (``body_models/smplh/female/model.npz``).
:class:`ModelCache` keeps one loaded model per (model type, gender), and :class:`Evaluator` turns a
:class:`~smplcore.motion.Motion` into joints (and vertices) in chunks of frames, with NumPy or, when
available, PyTorch on the CPU.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.family.specs import get_spec

GENDERS = ("neutral", "male", "female")
_GENDER_ALIASES = {
    "m": "male",
    "man": "male",
    "f": "female",
    "woman": "female",
    "n": "neutral",
    "": "neutral",
}

# How a motion's gender picks the model's gender:
#   "file"        the gender the file names (male, female or neutral);
#   "humanml3d"   male if the file says male, else female (HumanML3D's rule: neutral goes to female);
#   "neutral" / "male" / "female": always that gender.
GENDER_RULES = ("file", "humanml3d", *GENDERS)


def normalize_gender(gender: str) -> str:
    """``male``, ``female`` or ``neutral`` from the spellings motion files use (``b'female'``, ``F``...)."""
    g = str(gender).strip().lower()
    g = _GENDER_ALIASES.get(g, g)
    if g not in GENDERS:
        raise ValueError(f"gender: expected one of {GENDERS}, got {gender!r}")
    return g


def pick_gender(file_gender: str, rule: str = "file") -> str:
    """The model gender for a motion whose file names ``file_gender``, under ``rule`` (see GENDER_RULES)."""
    if rule not in GENDER_RULES:
        raise ValueError(f"gender rule: expected one of {GENDER_RULES}, got {rule!r}")
    if rule in GENDERS:
        return rule
    g = normalize_gender(file_gender)
    if rule == "humanml3d":
        return "male" if g == "male" else "female"
    return g


@dataclass
class LoadedModel:
    """A body model ready to evaluate: the NumPy model and, for the torch backend, its torch arrays."""

    model: Any  # smplcore.BodyModel
    path: Path
    gender: str
    backend: str
    torch_arrays: Any = None
    torch_source: Any = None  # the model's arrays as torch tensors (smplcore.model.model_arrays)

    @property
    def model_type(self) -> str:
        return self.model.model_type

    @property
    def num_betas(self) -> int:
        return self.model.num_betas

    @property
    def num_vertices(self) -> int:
        return int(self.model.rig.num_vertices)


def torch_available() -> bool:
    """Whether PyTorch is installed (found without importing it: importing takes seconds)."""
    import importlib.util

    return importlib.util.find_spec("torch") is not None


def resolve_backend(backend: str, vertices: bool = False) -> str:
    """``numpy`` or ``torch``. ``auto`` is NumPy: on a CPU it is as fast as torch for joints (twice as
    fast on the skeleton-only path) and faster for vertices, and workers start without importing
    torch. ``vertices`` is kept for callers that pass it."""
    del vertices
    if backend == "auto":
        return "numpy"
    if backend not in ("numpy", "torch"):
        raise ValueError(f"backend: expected 'auto', 'numpy' or 'torch', got {backend!r}")
    if backend == "torch" and not torch_available():
        raise ValueError(
            "backend: 'torch' asked, but PyTorch is not installed; install it with: pip install torch==2.13.0, "
            "or use --backend numpy"
        )
    return backend


@dataclass
class ModelCache:
    """One loaded model per (model type, gender), as found by :func:`smplcore.io.locate.locate_model_file`
    (``ext`` None: ``npz`` first, AMASS's format, then ``pkl``).

    Models are evaluated as AMASS poses need: ``use_pca=False, flat_hand_mean=True`` (absolute
    hand poses). ``num_betas`` None keeps every shape component the file holds.
    """

    model_path: str | Path | None
    num_betas: int | None = None
    ext: str | None = None
    backend: str = "auto"
    dtype: Any = np.float32
    vertices: bool = False  # what the models will mostly compute (for backend "auto")
    dmpl_path: str | Path | None = None  # DMPL blend shapes for every model (see BodyModel's dmpl_path)
    skinning: str = "lbs"  # or "dqs": dual-quaternion skinning
    models: dict[tuple[str, str], LoadedModel] = field(default_factory=dict)

    def get(self, model_type: str, gender: str) -> LoadedModel:
        from smplcore.io import load_model, locate_model_file
        from smplcore.numpy_model import BodyModel

        spec = get_spec(model_type)
        single_file = self.model_path is not None and Path(self.model_path).is_file()
        fixed = single_file  # one model whatever the gender (the open model comes in three genders too)
        key = (spec.model_type, "any" if fixed else normalize_gender(gender))
        if key in self.models:
            return self.models[key]
        path = locate_model_file(self.model_path, key[0], gender="neutral" if fixed else key[1], ext=self.ext or "npz")
        data = load_model(
            path,
            model_type=None if spec.model_type == "open" else spec.model_type,
            gender=None if fixed else key[1],
        )
        num_betas = data.num_betas if self.num_betas is None else min(self.num_betas, data.num_betas)
        options: dict[str, Any] = {"num_betas": num_betas, "skinning": self.skinning}
        if spec.hand_blocks:
            options.update(use_pca=False, flat_hand_mean=True)
        if spec.has_expression:
            options["num_expression_coeffs"] = data.num_expression_coeffs
        if self.dmpl_path is not None:
            options["dmpl_path"] = self.dmpl_path
        model = BodyModel(data=data, dtype=self.dtype, **options)
        backend = resolve_backend(self.backend, self.vertices)
        loaded = LoadedModel(model, path, data.gender, backend)
        if backend == "torch":
            import torch

            from smplcore.model.evaluate import model_arrays

            loaded.torch_source = model_arrays(
                model, lambda a: torch.from_numpy(np.array(a, dtype=model.dtype, order="C", copy=True))
            )
            loaded.torch_arrays = loaded.torch_source.fast_arrays()
        self.models[key] = loaded
        return loaded


class Evaluator:
    """Joints (and vertices) of a motion under a loaded model, in chunks of frames.

    Parameters
    ----------
    chunk : frames per forward call for joints (None: 1024 with NumPy, 4096 with torch, the
        fastest sizes on a CPU: NumPy's temporaries then stay in cache).
    vertex_budget : bound on frames × vertices per forward call when vertices are built (the
        chunk shrinks so that a call's temporaries stay near 100 MB).
    """

    DEFAULT_CHUNK = {"numpy": 1024, "torch": 4096}

    def __init__(self, chunk: int | None = None, vertex_budget: int = 1_000_000) -> None:
        if chunk is not None and chunk < 1:
            raise ValueError(f"chunk: expected a positive number of frames, got {chunk}")
        self.chunk = None if chunk is None else int(chunk)
        self.vertex_budget = int(vertex_budget)

    def params(self, motion: Any, loaded: LoadedModel) -> dict[str, np.ndarray]:
        """The motion as keyword parameters of ``loaded`` (betas, expression and DMPL coefficients cut to the
        model's size; the motion's ``dmpls`` only for a model with DMPL blend shapes)."""
        from smplcore.model.params import fit_width  # the one coefficient rule

        model = loaded.model
        params = motion.model_params(model.model_type, model.skeleton_joint_names, model.num_betas)
        params["betas"] = fit_width("betas", params["betas"], model.num_betas)
        if "expression" in params:
            params["expression"] = fit_width("expression", params["expression"], model.num_expression_coeffs)
        if model.num_dmpls and motion.dmpls is not None:
            params["dmpls"] = fit_width("dmpls", np.asarray(motion.dmpls), model.num_dmpls)
        return {k: np.ascontiguousarray(v, dtype=model.dtype) for k, v in params.items()}

    def run(
        self, motion: Any, loaded: LoadedModel, *, vertices: bool = False, skeleton_only: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """``joints`` (T, J', 3) and ``vertices`` (T, V, 3) or None.

        The joints are the skeleton joints then the extra vertex joints and landmarks; with
        ``skeleton_only`` (and no vertices) only the J skeleton joints, by a shorter path that poses
        no vertex at all (about 1.5 times faster).
        """
        params = self.params(motion, loaded)
        frames = motion.num_frames
        chunk = self.chunk or self.DEFAULT_CHUNK[loaded.backend]
        if vertices:
            chunk = max(1, min(chunk, self.vertex_budget // max(1, loaded.num_vertices)))
        skeleton = skeleton_only and not vertices and _skeleton_path_applies(loaded)
        joints_out: list[np.ndarray] = []
        verts_out: list[np.ndarray] = []
        for start in range(0, frames, chunk):
            part = {
                k: (v[start : start + chunk] if v.shape[0] == frames and k != "betas" else v) for k, v in params.items()
            }
            if skeleton:
                joints, verts = _skeleton_joints(loaded, part), None
            else:
                joints, verts = self._forward(loaded, part, vertices)
            joints_out.append(joints)
            if verts is not None:
                verts_out.append(verts)
        if not joints_out:
            model = loaded.model
            count = len(model.skeleton_joint_names) if skeleton else len(model.joint_names)
            joints_out = [np.zeros((0, count, 3), model.dtype)]
            verts_out = [np.zeros((0, loaded.num_vertices, 3), model.dtype)] if vertices else []
        joints = np.concatenate(joints_out) if len(joints_out) > 1 else joints_out[0]
        verts = None
        if vertices:
            verts = np.concatenate(verts_out) if len(verts_out) > 1 else verts_out[0]
        return joints, verts

    @staticmethod
    def _forward(
        loaded: LoadedModel, params: dict[str, np.ndarray], vertices: bool
    ) -> tuple[np.ndarray, np.ndarray | None]:
        if loaded.backend == "numpy":
            out = loaded.model(return_verts=vertices, **params)
            return out.joints, out.vertices
        import torch

        from smplcore.model.evaluate import evaluate

        with torch.inference_mode():
            tensors = {k: torch.from_numpy(v) for k, v in params.items()}
            out = evaluate(loaded.model, tensors, arrays=loaded.torch_source, outputs="mesh" if vertices else "joints")
            # an Evaluation's vertices and joints are both translated already
            joints = out.joints.numpy()
            verts = None if out.vertices is None else out.vertices.numpy()
        return joints, verts


def _skeleton_path_applies(loaded: LoadedModel) -> bool:
    """The skeleton-only path covers axis-angle poses with no hand PCA and no mean pose (AMASS's case)."""
    rig = loaded.model.rig
    return not rig.hand_components and not np.any(rig.pose_mean)


def _skeleton_joints(loaded: LoadedModel, params: dict[str, Any]) -> np.ndarray:
    """(B, J, 3) posed skeleton joints (translation included): rotations, rest joints, kinematic chain.

    The same engine functions as a full forward pass, minus what only the mesh and the extra vertex
    joints need (skinning transforms, pose correctives, skinning); the shape's rest joints are
    computed once per chunk when the betas are shared by every frame.
    """
    from smplcore.engine import rest_joints, rodrigues, world_transforms
    from smplcore.model.params import fit_width

    rig = loaded.model.rig
    torch_backend = loaded.backend == "torch"
    xp: Any  # torch or numpy: the array namespace of the chosen backend
    if torch_backend:
        import torch

        xp, arrays = torch, loaded.torch_arrays
        params = {k: torch.from_numpy(v) for k, v in params.items()}
    else:
        xp, arrays = np, loaded.model.arrays
    transl = params["transl"]
    batch = transl.shape[0]
    dtype = loaded.model.dtype

    def zeros(rows: int, width: int) -> Any:
        z = np.zeros((rows, width), dtype)
        return torch.from_numpy(z) if torch_backend else z

    def coefficients(name: str, width: int) -> Any:
        value = params.get(name)
        return zeros(1, width) if value is None else fit_width(name, value, width)

    def run() -> np.ndarray:
        blocks = [params[b.name] if b.name in params else zeros(batch, 3 * b.num_joints) for b in rig.pose_blocks]
        rotmats = rodrigues(xp.concat(blocks, axis=1).reshape(batch, -1, 3))
        parts = [coefficients("betas", rig.num_betas)]  # the order of rig.blend_dirs
        if rig.num_expression_coeffs:
            parts.append(coefficients("expression", rig.num_expression_coeffs))
        if rig.num_dmpls:
            parts.append(coefficients("dmpls", rig.num_dmpls))
        rows = max(p.shape[0] for p in parts)
        parts = [
            p
            if p.shape[0] == rows
            else (p[:1].expand(rows, -1) if torch_backend else np.broadcast_to(p[:1], (rows,) + p.shape[1:]))
            for p in parts
        ]
        coeffs = parts[0] if len(parts) == 1 else xp.concat(parts, axis=1)
        rest = rest_joints(coeffs, arrays)
        if rest.shape[0] != batch:
            rest = rest.expand(batch, -1, -1) if torch_backend else np.broadcast_to(rest, (batch,) + rest.shape[1:])
        _, posed = world_transforms(rotmats, rest, arrays.tree)
        out = posed + transl[:, None]
        return out.numpy() if torch_backend else out

    if torch_backend:
        with torch.inference_mode():
            return run()
    return run()
