"""``smplcore measure``: measurements of a body (model + betas, a motion or fit .npz, or a mesh file), and
``--fit`` shapes from measurements."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.measure.definitions import UNITS

_MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None


def _targets(text: str) -> dict[str, float]:
    out = {}
    for item in text.replace(" ", "").split(","):
        if not item:
            continue
        name, _, value = item.partition("=")
        try:
            out[name] = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected name=value pairs like height=1.8,waist=0.85, got {item!r}"
            ) from None
    return out


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``smplcore measure``."""
    p = subparsers.add_parser(
        "measure",
        help="anthropometric measurements of a body (stature, mass, girths, ...), or betas from measurements",
        description="Measure a body: the open model (or --model-path) with --betas, the first frame's shape of "
        "INPUT (an AMASS-style motion or a `smplcore fit` .npz with 'betas'), or a mesh file (.obj/.ply/...) "
        "with the model's vertex count (its joints come from the model's regressor). Definitions follow ISO "
        "8559-1 / ISO 7250-1 / ANSUR II (docs/measure.md). With --fit, solve for betas instead.",
    )
    p.add_argument("input", nargs="?", type=Path, default=None, metavar="INPUT", help="a .npz with betas, or a mesh")
    p.add_argument("--model-path", default=None, help="model file or folder (default: the open model)")
    p.add_argument("--model-type", default=None, help="smpl, smplh, smplx or open")
    p.add_argument("--gender", default=None, help="model gender (default: the input's, else neutral)")
    p.add_argument("--age", type=float, default=None, help="the open model at this age in years, 1-90")
    p.add_argument("--betas", type=_floats, default=None, help="shape coefficients, e.g. '1.5,-0.5'")
    p.add_argument("--names", default=None, help="measurements to print, comma separated (default: all)")
    p.add_argument("--density", type=float, default=None, help="body density in kg/m^3 for the mass")
    p.add_argument(
        "--fit",
        type=_targets,
        default=None,
        metavar="NAME=VALUE,...",
        help="solve for betas with these measurements (metres, kg), e.g. height=1.80,mass=80,waist=0.90",
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(run=run_measure)


def _npz_betas(path: Path) -> tuple[np.ndarray, str | None]:
    with np.load(path, allow_pickle=False) as data:
        if "betas" not in data.files:
            raise ValueError(f"{path}: expected a 'betas' array in the .npz, found {sorted(data.files)}")
        betas = np.asarray(data["betas"], dtype=np.float64)
        gender = str(data["gender"]) if "gender" in data.files else None
    if betas.ndim == 2:
        betas = betas[0]
    return betas.reshape(-1), gender


def _model(args: argparse.Namespace, gender: str | None) -> Any:
    from smplcore import BodyModel

    model_type = args.model_type or (None if args.model_path else "open")
    options = {} if args.age is None else {"age": args.age}
    return BodyModel(
        args.model_path, model_type, gender=(args.gender or gender or "neutral"), dtype=np.float64, **options
    )


def _table(values: dict[str, float], title: str) -> str:
    lines = [title]
    for name, v in values.items():
        unit = UNITS.get(name, "")
        shown = f"{v * 100:8.1f} cm" if unit == "m" else f"{v:8.3f} {unit}" if unit == "m^3" else f"{v:8.1f} {unit}"
        lines.append(f"  {name:<17}{shown}")
    return "\n".join(lines)


def run_measure(args: argparse.Namespace) -> int:
    from smplcore.measure import fit_shape, measure, measure_mesh
    from smplcore.measure.definitions import DEFAULT_DENSITY

    density = DEFAULT_DENSITY if args.density is None else args.density
    names = None if args.names is None else [n.strip() for n in args.names.split(",") if n.strip()]
    betas, gender = (None, None)
    mesh = None
    if args.input is not None:
        if not args.input.exists():
            raise FileNotFoundError(f"INPUT: no such file {args.input}")
        if args.input.suffix.lower() in _MESH_SUFFIXES:
            mesh = args.input
        else:
            betas, gender = _npz_betas(args.input)
    if args.betas is not None:
        betas = np.asarray(args.betas, dtype=np.float64)
    model = _model(args, gender)
    if args.fit is not None:
        result = fit_shape(model, density=density, **args.fit)
        out = {
            "betas": [round(float(b), 6) for b in result.betas],
            "measured": result.measured,
            "residual": result.residual,
        }
        if args.json:
            print(json.dumps(out, indent=2))
        else:
            print("betas: " + ", ".join(f"{b:.4f}" for b in result.betas))
            print(_table(result.measured, "measured:"))
            print(
                "residual (measured - target): "
                + ", ".join(
                    f"{k} {v * 100:+.2f} cm" if UNITS[k] == "m" else f"{k} {v:+.3f} {UNITS[k]}"
                    for k, v in result.residual.items()
                )
            )
        return 0
    if mesh is not None:
        import trimesh

        loaded: Any = trimesh.load(mesh, force="mesh", process=False)
        vertices = np.asarray(loaded.vertices, dtype=np.float64)
        from smplcore.measure._rig import _rig_of

        rig = _rig_of(model)
        if len(vertices) != rig.num_vertices:
            raise ValueError(
                f"{mesh}: expected a mesh of the model's {rig.num_vertices} vertices (its joints come from the "
                f"model's regressor), got {len(vertices)}; pass --model-path/--model-type for its model"
            )
        joints = dict(zip(rig.joint_names, np.asarray(rig.joint_regressor) @ vertices))
        values = measure_mesh(vertices, np.asarray(loaded.faces), joints, names=names, density=density)
        source = str(mesh)
    else:
        values = measure(model, betas, names=names, density=density)
        shape = "0" if betas is None else ", ".join(f"{b:g}" for b in betas)
        source = (
            str(args.input)
            if args.input is not None
            else f"{model.model_type}{'' if args.age is None else f' age {args.age:g}'} betas {shape}"
        )
    if args.json:
        print(json.dumps({"source": source, "units": {k: UNITS[k] for k in values}, "values": values}, indent=2))
    else:
        print(_table(values, f"{source}:"))
    return 0
