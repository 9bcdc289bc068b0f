# ruff: noqa: E501 - a table of cases, one per line
"""Hostile values for the fitting API and the forward's options: a table of cases and a classifier.

Each case is ``(surface, label, call)``; :func:`outcome` runs one and says how it ended:

* ``"clean"``: returned, every array in the result finite (and, for fits, errors finite);
* ``"flagged"``: returned, finite, with bodies marked not converged and a warning;
* ``"clear"``: a ValueError / TypeError (ShapeError, ModelFileError, FitError are ValueErrors) whose message
  names the argument (the case's ``names``);
* ``"raw"``: any other exception, or a clear type whose message does not name the argument;
* ``"nonfinite"``: returned with a NaN / inf value in a parameter or an error.

Run it as a script for the table of outcomes (``python tests/probe_fit_api.py``); ``tests/test_probe_fit_api.py``
asserts that no case is ``raw`` or ``nonfinite``.
"""

from __future__ import annotations

import json
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


@dataclass(frozen=True)
class Case:
    surface: str
    label: str
    call: Callable[[Path], Any]
    names: tuple[str, ...]  # one of these must appear in a clear error's message


def _model():
    import smplcore

    return smplcore.BodyModel(model_type="open", dtype=np.float64)


_CACHE: dict[str, Any] = {}


def model():
    if "m" not in _CACHE:
        _CACHE["m"] = _model()
    return _CACHE["m"]


def joints_target(batch: int = 2) -> np.ndarray:
    rng = np.random.default_rng(0)
    return model()(body_pose=rng.normal(0, 0.2, (batch, 69))).joints[:, :22]


def vertices_target(batch: int = 1) -> np.ndarray:
    rng = np.random.default_rng(1)
    return model()(body_pose=rng.normal(0, 0.2, (batch, 69)), betas=rng.normal(0, 1, (batch, 10))).vertices


def camera(**kw):
    from smplcore.fit import Camera

    return Camera(**{"focal": 1000.0, "center": (320.0, 240.0), **kw})


def keypoints_target(batch: int = 1) -> np.ndarray:
    from smplcore import keypoints as kp

    m = model()
    out = m(global_orient=np.tile([np.pi, 0, 0], (batch, 1)), transl=np.tile([0.0, 0.3, 4.0], (batch, 1)))
    pts, _ = kp.convert(out.joints, m, "coco17")
    uv = camera().project(pts)
    return np.concatenate([uv, np.ones((*uv.shape[:-1], 1))], axis=-1)


def _fit(name: str):
    from smplcore import fit

    return getattr(fit, name)


def fj(**kw):
    args = {"model": model(), "joints": joints_target(), **kw}
    return _fit("fit_joints")(**args)


def fv(**kw):
    args = {"model": model(), "vertices": vertices_target(), "max_iter": 3, **kw}
    return _fit("fit_vertices")(**args)


def fk(**kw):
    args = {
        "model": model(),
        "keypoints": keypoints_target(),
        "convention": "coco17",
        "camera": camera(),
        "multi_start": False,
        "max_iter": 5,
        **kw,
    }
    return _fit("fit_keypoints")(**args)


def cv(**kw):
    args = {"params": {"body_pose": np.full((1, 69), 0.1)}, "source_model": model(), "target_model": model(), **kw}
    return _fit("convert")(**args)


def _write(tmp: Path, name: str, text: str) -> Path:
    path = tmp / name
    path.write_text(text)
    return path


def _deep_json(depth: int) -> str:
    return "[" * depth + "]" * depth


def _cases() -> list[Case]:
    cases: list[Case] = []

    def add(surface: str, label: str, call: Callable[[Path], Any], *names: str) -> None:
        cases.append(Case(surface, label, call, names))

    # -- fit_joints ------------------------------------------------------------------------------
    add("fit_joints", "clean", lambda t: fj(), "")
    add("fit_joints", "empty batch", lambda t: fj(joints=np.zeros((0, 22, 3))), "joints")
    add("fit_joints", "no joints", lambda t: fj(joints=np.zeros((2, 0, 3))), "joints")
    add("fit_joints", "1-D joints", lambda t: fj(joints=np.zeros(3)), "joints")
    add("fit_joints", "joints as str", lambda t: fj(joints="abc"), "joints")
    add("fit_joints", "joints None", lambda t: fj(joints=None), "joints")
    add("fit_joints", "NaN joints", lambda t: fj(joints=joints_target() * np.nan), "joints")
    add("fit_joints", "inf joints", lambda t: fj(joints=joints_target() + np.inf), "joints")
    add("fit_joints", "1e300 joints", lambda t: fj(joints=joints_target() * 1e300), "joints")
    add("fit_joints", "joints in mm", lambda t: fj(joints=joints_target() * 1000), "joints")
    add("fit_joints", "joints 1e6 m away", lambda t: fj(joints=joints_target() + 1e6), "joints")
    add("fit_joints", "all joints equal", lambda t: fj(joints=np.zeros((2, 22, 3))), "joints")
    for bad in (np.nan, np.inf, -1.0, "x", None, True, [1.0], 1e300):
        for opt in ("shape_prior", "pose_prior", "smoothness", "tol"):
            add("fit_joints", f"{opt}={bad!r}", lambda t, o=opt, b=bad: fj(**{o: b}), opt)
    for bad in (-1, 1.5, np.nan, "3", None, 10**12):
        add("fit_joints", f"max_iter={bad!r}", lambda t, b=bad: fj(max_iter=b), "max_iter")
        add("fit_joints", f"smoothing_rounds={bad!r}", lambda t, b=bad: fj(smoothing_rounds=b, smoothness=1e-3),
            "smoothing_rounds")  # fmt: skip
        add("fit_joints", f"workers={bad!r}", lambda t, b=bad: fj(workers=b), "workers")
    add("fit_joints", "workers=0", lambda t: fj(workers=0), "workers")
    add("fit_joints", "NaN joint_weights", lambda t: fj(joint_weights=np.full(22, np.nan)), "joint_weights")
    add("fit_joints", "inf joint_weights", lambda t: fj(joint_weights=np.full(22, np.inf)), "joint_weights")
    add("fit_joints", "zero joint_weights", lambda t: fj(joint_weights=np.zeros(22)), "joint_weights")
    add("fit_joints", "negative joint_weights", lambda t: fj(joint_weights=-np.ones(22)), "joint_weights")
    add("fit_joints", "joint_weights wrong size", lambda t: fj(joint_weights=np.ones(5)), "joint_weights")
    add("fit_joints", "joint_weights str", lambda t: fj(joint_weights="a"), "joint_weights")
    add("fit_joints", "unknown joint_names", lambda t: fj(joint_names=["x"] * 22), "joint_names")
    add("fit_joints", "joint_names unhashable", lambda t: fj(joint_names=[[1]] * 22), "joint_names")
    add("fit_joints", "joint_names int", lambda t: fj(joint_names=5), "joint_names")
    add("fit_joints", "betas NaN", lambda t: fj(betas=np.full(10, np.nan)), "betas")
    add("fit_joints", "betas wrong width", lambda t: fj(betas=np.zeros((2, 2, 2))), "betas")
    add("fit_joints", "init not a dict", lambda t: fj(init=[1, 2]), "init")
    add("fit_joints", "init unknown key", lambda t: fj(init={"bogus": np.zeros(3)}), "init")
    add("fit_joints", "init NaN pose", lambda t: fj(init={"body_pose": np.full(69, np.nan)}), "body_pose")
    add("fit_joints", "model None", lambda t: _fit("fit_joints")(None, joints_target()), "model")
    add("fit_joints", "model str", lambda t: _fit("fit_joints")("smpl", joints_target()), "model")

    # -- fit_vertices ----------------------------------------------------------------------------
    add("fit_vertices", "clean", lambda t: fv(), "")
    add("fit_vertices", "empty batch", lambda t: fv(vertices=vertices_target()[:0]), "vertices")
    add("fit_vertices", "wrong vertex count", lambda t: fv(vertices=np.zeros((1, 10, 3))), "vertices")
    add("fit_vertices", "NaN vertices", lambda t: fv(vertices=vertices_target() * np.nan), "vertices")
    add("fit_vertices", "vertices in mm", lambda t: fv(vertices=vertices_target() * 1000), "vertices")
    add("fit_vertices", "vertices 1e300", lambda t: fv(vertices=vertices_target() * 1e300), "vertices")
    add("fit_vertices", "vertex_ids out of range", lambda t: fv(vertices=np.zeros((1, 3, 3)), vertex_ids=[0, 1, 10**7]),
        "vertex_ids")  # fmt: skip
    add("fit_vertices", "vertex_ids negative", lambda t: fv(vertices=np.zeros((1, 3, 3)), vertex_ids=[-1, 0, 1]),
        "vertex_ids")  # fmt: skip
    add("fit_vertices", "vertex_ids float", lambda t: fv(vertices=np.zeros((1, 3, 3)), vertex_ids=[0.5, 1, 2]),
        "vertex_ids")  # fmt: skip
    add("fit_vertices", "vertex_ids empty", lambda t: fv(vertices=np.zeros((1, 0, 3)), vertex_ids=[]), "vertex")
    add(
        "fit_vertices",
        "NaN vertex_weights",
        lambda t: fv(vertex_weights=np.full(vertices_target().shape[1], np.nan)),
        "vertex_weights",
    )
    add(
        "fit_vertices",
        "zero vertex_weights",
        lambda t: fv(vertex_weights=np.zeros(vertices_target().shape[1])),
        "vertex_weights",
    )
    for bad in (np.nan, np.inf, -1.0, "x", None):
        for opt in ("shape_prior", "pose_prior", "tol"):
            add("fit_vertices", f"{opt}={bad!r}", lambda t, o=opt, b=bad: fv(**{o: b}), opt)
    for bad in (-1, 1.5, "3", None):
        add("fit_vertices", f"max_iter={bad!r}", lambda t, b=bad: fv(max_iter=b), "max_iter")
        add("fit_vertices", f"init_iterations={bad!r}", lambda t, b=bad: fv(init_iterations=b), "init_iterations")
    add("fit_vertices", "joints NaN", lambda t: fv(joints=np.full((1, 22, 3), np.nan)), "joints")
    add("fit_vertices", "joints wrong batch", lambda t: fv(joints=np.zeros((5, 22, 3))), "joints")

    # -- fit_keypoints ---------------------------------------------------------------------------
    add("fit_keypoints", "clean", lambda t: fk(), "")
    add("fit_keypoints", "empty batch", lambda t: fk(keypoints=np.zeros((0, 17, 3))), "keypoints")
    add("fit_keypoints", "min_points=0 no visible", lambda t: fk(keypoints=np.zeros((1, 17, 3)), min_points=0),
        "min_points", "keypoints")  # fmt: skip
    for bad in (-1, 1.5, "3", None, np.nan):
        add("fit_keypoints", f"min_points={bad!r}", lambda t, b=bad: fk(min_points=b), "min_points")
    add("fit_keypoints", "focal 1e300", lambda t: fk(camera=camera(focal=1e300)), "focal")
    add("fit_keypoints", "focal 1e-300", lambda t: fk(camera=camera(focal=1e-300)), "focal")
    add("fit_keypoints", "center 1e300", lambda t: fk(camera=camera(center=(1e300, 0))), "center")
    add("fit_keypoints", "keypoints 1e6 px off", lambda t: fk(keypoints=keypoints_target() + [1e6, 0, 0]),
        "keypoints")  # fmt: skip
    add("fit_keypoints", "keypoints 1e300", lambda t: fk(keypoints=keypoints_target() * [1e300, 1, 1]), "keypoints")
    add("fit_keypoints", "keypoints all equal", lambda t: fk(keypoints=np.tile([320.0, 240, 1], (1, 17, 1))),
        "keypoints")  # fmt: skip
    add("fit_keypoints", "NaN confidence", lambda t: fk(keypoints=keypoints_target() * [1, 1, np.nan]), "keypoints")
    add("fit_keypoints", "negative confidence", lambda t: fk(keypoints=keypoints_target() * [1, 1, -1]), "keypoints")
    add("fit_keypoints", "keypoints 2 columns", lambda t: fk(keypoints=keypoints_target()[..., :2]), "keypoints")
    add("fit_keypoints", "anneal=()", lambda t: fk(anneal=()), "anneal")
    add("fit_keypoints", "anneal=(nan,)", lambda t: fk(anneal=(np.nan,)), "anneal")
    add("fit_keypoints", "anneal=(-1,)", lambda t: fk(anneal=(-1.0,)), "anneal")
    add("fit_keypoints", "anneal='ab'", lambda t: fk(anneal="ab"), "anneal")
    add("fit_keypoints", "anneal=3", lambda t: fk(anneal=3), "anneal")
    for bad in (np.nan, np.inf, -1.0, "x", None):
        for opt in ("sigma", "shape_prior", "pose_prior", "joint_limits", "bending", "gmm_weight", "vposer_weight",
                    "focal_prior", "smoothness", "min_confidence", "tol"):  # fmt: skip
            add("fit_keypoints", f"{opt}={bad!r}", lambda t, o=opt, b=bad: fk(**{o: b}), opt)
    add("fit_keypoints", "sigma=0", lambda t: fk(sigma=0.0), "sigma")
    for bad in (-1, 1.5, "3", None):
        add("fit_keypoints", f"max_iter={bad!r}", lambda t, b=bad: fk(max_iter=b), "max_iter")
    add("fit_keypoints", "camera None", lambda t: fk(camera=None), "camera")
    add("fit_keypoints", "camera dict", lambda t: fk(camera={"focal": 1}), "camera")
    add("fit_keypoints", "convention unknown", lambda t: fk(convention="nope"), "convention")
    add("fit_keypoints", "convention int", lambda t: fk(convention=5), "convention")
    add("fit_keypoints", "convention list of ints", lambda t: fk(convention=[1, 2, 3]), "convention")
    add("fit_keypoints", "convention unhashable names", lambda t: fk(convention=[[1]] * 17), "convention")
    add("fit_keypoints", "gmm missing file", lambda t: fk(gmm=t / "none.pkl"), "gmm", "none.pkl")
    add("fit_keypoints", "gmm int", lambda t: fk(gmm=5), "gmm")
    add("fit_keypoints", "vposer int", lambda t: fk(vposer=5), "vposer")
    add("fit_keypoints", "regressor str", lambda t: fk(regressor="x"), "regressor")
    add("fit_keypoints", "estimate_focal empty", lambda t: fk(keypoints=np.zeros((0, 17, 3)), estimate_focal=True),
        "keypoints")  # fmt: skip

    # -- camera ------------------------------------------------------------------------------------
    for label, kw, name in (
        ("focal 0", {"focal": 0.0}, "focal"),
        ("focal -1", {"focal": -1.0}, "focal"),
        ("focal nan", {"focal": np.nan}, "focal"),
        ("focal str", {"focal": "x"}, "focal"),
        ("focal None", {"focal": None}, "focal"),
        ("focal 3 values", {"focal": [1.0, 2.0, 3.0]}, "focal"),
        ("focal 1e300", {"focal": 1e300}, "focal"),
        ("center nan", {"center": (np.nan, 0.0)}, "center"),
        ("center str", {"center": "ab"}, "center"),
        ("center 1 value", {"center": (1.0,)}, "center"),
        ("rotation not orthonormal", {"rotation": np.ones((3, 3))}, "rotation"),
        ("rotation str", {"rotation": "x"}, "rotation"),
        ("translation nan", {"translation": [np.nan, 0, 0]}, "translation"),
        ("translation 1e300", {"translation": [1e300, 0, 0]}, "translation"),
    ):
        add("camera", label, lambda t, k=kw: camera(**k), name)
    add("camera", "from_image_size nan", lambda t: __import__("smplcore").fit.Camera.from_image_size(np.nan, 10),
        "width")  # fmt: skip
    add("camera", "from_image_size str", lambda t: __import__("smplcore").fit.Camera.from_image_size("a", 10),
        "width")  # fmt: skip
    add("camera", "project str", lambda t: camera().project("abc"), "points")

    # -- convert -----------------------------------------------------------------------------------
    add("convert", "clean", lambda t: cv(), "")
    add("convert", "empty batch", lambda t: cv(params={"body_pose": np.zeros((0, 69))}), "params", "batch")
    add("convert", "NaN params", lambda t: cv(params={"body_pose": np.full((1, 69), np.nan)}), "params")
    add("convert", "params not a dict", lambda t: cv(params=[1, 2]), "params")
    add("convert", "params unknown key", lambda t: cv(params={"bogus": np.zeros(3)}), "bogus", "params")
    add("convert", "method bad", lambda t: cv(method="x"), "method")
    add("convert", "points=0", lambda t: cv(points=0), "points")
    add("convert", "points=-5", lambda t: cv(points=-5), "points")
    add("convert", "points str", lambda t: cv(points="x"), "points")
    add("convert", "deformation_transfer missing", lambda t: cv(deformation_transfer=t / "none.pkl"), "none.pkl")
    add("convert", "unknown fit option", lambda t: cv(bogus=1), "bogus")

    # -- priors ------------------------------------------------------------------------------------
    def gmm(**kw):
        from smplcore.fit import GMMPrior

        args = {"means": np.zeros((2, 3)), "covars": np.tile(np.eye(3), (2, 1, 1)), "weights": np.ones(2), **kw}
        return GMMPrior.from_arrays(**args)

    add("priors", "gmm clean", lambda t: gmm(), "")
    add("priors", "gmm empty", lambda t: gmm(means=np.zeros((0, 3)), covars=np.zeros((0, 3, 3)), weights=np.zeros(0)),
        "weights", "means", "mixture")  # fmt: skip
    add("priors", "gmm str means", lambda t: gmm(means="x"), "means")
    add("priors", "gmm NaN weights", lambda t: gmm(weights=np.array([np.nan, 1.0])), "weights", "non-finite")
    add("priors", "gmm singular covars", lambda t: gmm(covars=np.zeros((2, 3, 3))), "covar")
    add("priors", "gmm marginal 0", lambda t: gmm().marginal(0), "dim", "gmm")
    add("priors", "gmm marginal -1", lambda t: gmm().marginal(-1), "dim", "gmm")
    add("priors", "gmm load dir", lambda t: __import__("smplcore").fit.GMMPrior.load(t), "gmm", "no such file", "tmp")
    add("priors", "vposer load missing", lambda t: __import__("smplcore").fit.VPoserPrior.load(t / "x"), "x")

    # -- keypoint readers --------------------------------------------------------------------------
    def coco(doc: Any) -> Any:
        from smplcore import keypoints as kp

        return kp.read_coco(_write(Path(_CACHE["tmp"]), "coco.json", json.dumps(doc)))

    def openpose(doc: Any) -> Any:
        from smplcore import keypoints as kp

        return kp.read_openpose(_write(Path(_CACHE["tmp"]), "op.json", json.dumps(doc)))

    ann = {"image_id": 1, "keypoints": [1.0, 2.0, 2] * 17}
    add("readers", "coco clean", lambda t: coco({"annotations": [ann]}), "")
    add("readers", "coco unhashable image_id list", lambda t: coco({"annotations": [{**ann, "image_id": [1]}]}),
        "image_id")  # fmt: skip
    add("readers", "coco unhashable image_id dict", lambda t: coco({"annotations": [{**ann, "image_id": {"a": 1}}]}),
        "image_id")  # fmt: skip
    add("readers", "coco image ids mixed types", lambda t: coco({"annotations": [ann, {**ann, "image_id": "a"}]}), "")
    add("readers", "coco images with unhashable id", lambda t: coco({"annotations": [ann], "images": [{"id": [1]}]}),
        "images", "id")  # fmt: skip
    add("readers", "coco NaN keypoint", lambda t: coco({"annotations": [{**ann, "keypoints": [float("nan")] * 51}]}),
        "keypoints")  # fmt: skip
    add("readers", "coco max_people=-1", lambda t: __import__("smplcore").keypoints.read_coco(
        _write(t, "c.json", json.dumps({"annotations": [ann]})), max_people=-1), "max_people")  # fmt: skip
    add("readers", "coco deep JSON", lambda t: __import__("smplcore").keypoints.read_coco(
        _write(t, "deep.json", _deep_json(100_000))), "deep.json")  # fmt: skip
    add("readers", "openpose deep JSON", lambda t: __import__("smplcore").keypoints.read_openpose(
        _write(t, "deep.json", _deep_json(100_000))), "deep.json")  # fmt: skip
    add("readers", "coco categories keypoints str", lambda t: coco(
        {"annotations": [{**ann, "keypoints": [1.0, 2.0, 2] * 5}], "categories": [{"keypoints": "abc"}]}),
        "keypoints", "categories")  # fmt: skip
    add("readers", "coco categories not list", lambda t: coco(
        {"annotations": [{**ann, "keypoints": [1.0, 2.0, 2] * 5}], "categories": 5}), "keypoints", "categories")  # fmt: skip
    add("readers", "openpose people str", lambda t: openpose({"people": "x"}), "people")
    add("readers", "openpose NaN", lambda t: openpose({"people": [{"pose_keypoints_2d": [float("inf")] * 75}]}),
        "pose_keypoints_2d")  # fmt: skip
    add("readers", "openpose max_people=-1", lambda t: __import__("smplcore").keypoints.read_openpose(
        _write(t, "o.json", json.dumps({"people": []})), max_people=-1), "max_people")  # fmt: skip
    add("readers", "openpose empty list", lambda t: __import__("smplcore").keypoints.read_openpose([]), "source")
    add("readers", "openpose source int", lambda t: __import__("smplcore").keypoints.read_openpose(5), "source")

    # -- forward and front-end options ----------------------------------------------------------
    def bm(**kw):
        import smplcore

        return smplcore.BodyModel(model_type="open", **kw)

    for opt, bad in (("num_betas", -1), ("num_betas", 1.5), ("num_betas", "3"), ("num_betas", None),
                     ("dtype", "float7"), ("dtype", int), ("kernel", 5), ("skinning", None), ("age", 5),
                     ("gender", 5), ("gender", "alien"), ("v_template", "x"), ("v_template", np.full((13380, 3), np.nan)),
                     ("joint_regressors", 5), ("dmpl_path", 5)):  # fmt: skip
        add("front end", f"BodyModel {opt}={bad!r}", lambda t, o=opt, b=bad: bm(**{o: b}), opt)
    add("forward", "betas str", lambda t: bm()(betas="x"), "betas")
    add("forward", "betas NaN", lambda t: bm()(betas=np.full((1, 10), np.nan)), "betas")
    add("forward", "transl 1e300", lambda t: bm()(transl=np.full((1, 3), 1e300)), "transl")
    add("forward", "body_pose 1e300", lambda t: bm()(body_pose=np.full((1, 69), 1e300)), "body_pose")
    add("forward", "betas 1e300", lambda t: bm()(betas=np.full((1, 10), 1e300)), "betas")
    add(
        "forward", "batch mismatch", lambda t: bm()(betas=np.zeros((2, 10)), transl=np.zeros((3, 3))), "transl", "batch"
    )
    add("forward", "empty batch", lambda t: bm()(betas=np.zeros((0, 10))), "")
    add("forward", "unknown keyword", lambda t: bm()(bogus=1), "bogus")
    add("forward", "pose 4-D", lambda t: bm()(body_pose=np.zeros((1, 1, 1, 69))), "body_pose")
    return cases


CASES = _cases()


def _finite(value: Any) -> bool:
    if value is None:
        return True
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(_finite(v) for v in value)
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    if isinstance(value, np.ndarray) and value.dtype.kind in "fc":
        return bool(np.all(np.isfinite(value)))
    if isinstance(value, float):
        return bool(np.isfinite(value))
    return True


def _result_arrays(result: Any) -> list[Any]:
    out = []
    for name in ("params", "vertex_error", "joint_error", "reprojection_error", "vertices", "joints", "points"):
        if hasattr(result, name):
            out.append(getattr(result, name))
    if isinstance(result, np.ndarray):
        out.append(result)
    return out


def outcome(case: Case, tmp: Path) -> tuple[str, str]:
    """(kind, detail) for one case (see the module docstring)."""
    _CACHE["tmp"] = str(tmp)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = case.call(tmp)
        except (ValueError, TypeError) as exc:
            message = str(exc)
            named = any(n and n.lower() in message.lower() for n in case.names)
            kind = "clear" if named else "raw"
            return kind, f"{type(exc).__name__}: {message[:160]}"
        except Exception as exc:  # noqa: BLE001 - the probe classifies every exception
            return "raw", f"{type(exc).__name__}: {str(exc)[:160]}"
    if not all(_finite(a) for a in _result_arrays(result)):
        return "nonfinite", "a returned value is NaN or infinite"
    converged = getattr(result, "converged", None)
    if converged is not None and len(converged) and not np.all(converged) and caught:
        return "flagged", str(caught[0].message)[:160]
    return "clean", ""


def main() -> None:
    import tempfile
    from collections import Counter

    counts: dict[str, Counter] = {}
    with tempfile.TemporaryDirectory() as tmp:
        wanted = [a for a in sys.argv[1:] if not a.startswith("-")]
        for case in CASES:
            if wanted and case.surface not in wanted:
                continue
            kind, detail = outcome(case, Path(tmp))
            counts.setdefault(case.surface, Counter())[kind] += 1
            if kind in ("raw", "nonfinite") or "-v" in sys.argv:
                print(f"{kind:9s} {case.surface:14s} {case.label:34s} {detail}", flush=True)
    print(f"{'surface':14s} {'cases':>5s} {'clear':>5s} {'flagged':>7s} {'clean':>5s} {'raw':>4s} {'nonfinite':>9s}")
    for surface, c in counts.items():
        print(
            f"{surface:14s} {sum(c.values()):5d} {c['clear']:5d} {c['flagged']:7d} {c['clean']:5d} {c['raw']:4d} "
            f"{c['nonfinite']:9d}"
        )


if __name__ == "__main__":
    main()
