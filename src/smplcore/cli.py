"""The ``smplcore`` command line: a thin layer over library functions."""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

from smplcore.cli_options import model_file_options
from smplcore.errors import ModelFileError, ShapeError

# Modules that add their own subcommand: each has ``add_parser(subparsers)`` registering a parser whose
# ``run`` default is a function ``(args) -> exit status``.
_SUBCOMMAND_MODULES = (
    "smplcore.export.cli",
    "smplcore.fit.cli",
    "smplcore.motion.cli",
    "smplcore.view.cli",
    "smplcore.measure.cli",
)


def _version() -> str:
    from smplcore import __version__

    return __version__


def _parse_floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None


def _cmd_demo(args: argparse.Namespace) -> int:
    from smplcore.demo import run_demo

    result = run_demo(
        args.out,
        poses=args.poses,
        pose_file=args.pose,
        betas=args.betas,
        model_path=args.model_path,
        model_type=args.model_type,
        gender=args.gender,
        ext=args.ext,
        use_pca=args.use_pca,
        mesh_format=args.format,
        render=not args.no_render,
        texture=None if args.texture == "none" else args.texture,
        age=args.age,
    )
    print(f"mesh:  {result.mesh_path}")
    if result.texture_path is not None:
        print(f"texture: {result.texture_path}")
    if result.image_path is not None:
        print(f"image: {result.image_path}")
    return 0


def _cmd_convert(args: argparse.Namespace) -> int:
    from smplcore.io import convert

    output = Path(args.output)
    if output.is_dir() or not output.suffix or str(args.output).endswith(("/", "\\")):
        output = output / f"{Path(args.input).stem}.npz"  # a folder (created): the input's name, as .npz
    out = convert(args.input, output, model_type=args.model_type, gender=args.gender)
    print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="smplcore", description="SMPL-family body models: fast, exact, safe.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="pose a body model and write a mesh and a rendered PNG")
    demo.add_argument("--out", type=Path, default=Path("smplcore-demo"), help="output folder (default: %(default)s)")
    demo.add_argument(
        "--poses",
        nargs="+",
        default=None,
        help="named poses: t-pose a-pose walk wave squat (default: a-pose walk wave squat)",
    )
    demo.add_argument("--pose", type=Path, default=None, help="file of body poses (.npy/.npz/.txt; 69 or 72 values)")
    demo.add_argument("--betas", type=_parse_floats, default=None, help="shape coefficients, e.g. '1.5,-0.5'")
    demo.add_argument("--model-path", default=None, help="your model file or folder (default: the open model)")
    demo.add_argument("--model-type", default=None, help="smpl, smplh, smplx or open")
    demo.add_argument("--gender", default="neutral")
    model_file_options(demo, use_pca_default="when the model file has a hand PCA; an AMASS SMPL+H .npz has none")
    demo.add_argument("--format", choices=("obj", "ply"), default="obj", help="mesh format (default: obj)")
    demo.add_argument("--no-render", action="store_true", help="skip the PNG")
    demo.add_argument(
        "--texture",
        default="uv-grid",
        metavar="FILE",
        help="image drawn on the body through the model's UV map (the open model, SMPL-X), in the PNG and "
        "with the OBJ; 'uv-grid' (default) a generated grid that shows the mapping; 'none' for no texture",
    )
    demo.add_argument(
        "--age", type=float, default=None, help="the open model at this age in years, 1-90 (default: the adult)"
    )
    demo.set_defaults(run=_cmd_demo)

    conv = sub.add_parser(
        "convert",
        help="rewrite any model file as a clean, pickle-free .npz",
        description="Read a model file (official .pkl or .npz of SMPL, SMPL+H, SMPL-X, MANO, FLAME; nothing in it "
        "is run) and write it as smplcore's .npz, which loads with numpy alone (no pickle, no chumpy). smplcore "
        "reads the result anywhere a model file is taken; smplx cannot read it.",
    )
    conv.add_argument("input", type=Path, metavar="IN", help="the model file to read (.pkl or .npz)")
    conv.add_argument(
        "output",
        type=Path,
        metavar="OUT",
        help="the .npz to write, or a folder (created if missing) to write IN's name with .npz into",
    )
    conv.add_argument(
        "--model-type",
        default=None,
        help="smpl, smplh, smplx, mano or flame (default: from the file name, else from the file's joints)",
    )
    conv.add_argument(
        "--gender", default=None, help="gender (MANO: right/left) to record (default: from the file name)"
    )
    conv.set_defaults(run=_cmd_convert)

    for module_name in _SUBCOMMAND_MODULES:
        importlib.import_module(module_name).add_parser(sub)
    return parser


# A command whose extra brings several others: its missing-dependency line names it.
_COMMAND_EXTRAS = {"demo": ("demo", {"render", "export", "cli"})}


def _missing_dependency(command: str, exc: ImportError) -> str:
    """One line for a missing optional module: what needs it and the ``pip install "smplcore[extra]"`` line."""
    from smplcore._deps import MissingDependencyError, install_hint, missing

    if not isinstance(exc, MissingDependencyError):
        exc = missing(exc.name or "?", "this command", reason=str(exc))
    extra, covers = _COMMAND_EXTRAS.get(command, (None, set()))
    if extra and exc.extra in covers:
        return str(exc).replace(install_hint(exc.extra), install_hint(extra))
    return str(exc)


def main(argv: list[str] | None = None) -> int:
    from smplcore._deps import EXTRAS, MissingDependencyError

    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except (ModelFileError, ShapeError, ValueError, FileNotFoundError) as exc:
        print(f"smplcore {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:
        top = (exc.name or "").split(".")[0]
        if not isinstance(exc, MissingDependencyError) and top not in EXTRAS:
            raise  # not an optional dependency: a bug, shown in full
        print(f"smplcore {args.command}: {_missing_dependency(args.command, exc)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
