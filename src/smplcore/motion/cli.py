"""``smplcore process``: a tree of motion sequences to joints (and meshes); registered by smplcore.cli."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EPILOG = """\
examples:
  smplcore process amass/ joints/ --model-path body_models/ --fps 20
  smplcore process amass/ pose_data/ --model-path body_models/ --recipe humanml3d
  smplcore process amass/ meshes/ --model-path body_models/ --vertices --dtype float16
  smplcore process amass/ joints/ --model-path body_models/ --ray            # local Ray cluster
  smplcore process amass/ joints/ --model-path body_models/ --ray auto       # running cluster

The model folder may be laid out like smplx (body_models/smplh/SMPLH_FEMALE.npz) or like AMASS
(body_models/smplh/female/model.npz); each file uses the gendered model it names. A rerun skips
finished outputs; bad input files are reported, skipped and make the exit status 1.
Exit status: 0 all done, 1 files skipped (bad input), 2 bad arguments or folder, 3 the disk is full
(finished outputs are kept, the rest are marked not done; free space and rerun to resume),
130 interrupted. See docs/motion.md."""


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected 0 or more, got {text!r}")
    return value


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``smplcore process``."""
    from smplcore.motion.models import GENDER_RULES
    from smplcore.motion.process import RECIPES
    from smplcore.motion.resample import METHODS

    p = subparsers.add_parser(
        "process",
        help="turn a tree of AMASS-style sequences into joints (and meshes): parallel, resumable",
        description="Evaluate every AMASS-style .npz sequence under IN_DIR with its body model and write one "
        "output per input under OUT_DIR (same tree), plus OUT_DIR/manifest.json.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("input", type=Path, metavar="IN_DIR", help="folder of sequences (searched recursively) or one file")
    p.add_argument("output", type=Path, metavar="OUT_DIR", help="output folder")
    m = p.add_argument_group("model")
    m.add_argument("--model-path", default=None, help="model file or folder (default: the packaged open model)")
    m.add_argument("--model-type", default=None, help="smplh, smplx, smpl or open (default: the type each file names)")
    m.add_argument(
        "--gender",
        choices=GENDER_RULES,
        default=None,
        help="file: the gendered model each file names (default); humanml3d: male if the file says "
        "male, else female; or one fixed gender",
    )
    m.add_argument("--ext", choices=("npz", "pkl"), default=None, help="model file extension (default: npz, then pkl)")
    m.add_argument("--num-betas", type=_count, default=None, help="shape coefficients used (default: all)")
    m.add_argument(
        "--dmpl",
        default=None,
        metavar="FILE",
        help="DMPL soft-tissue blend shapes (dmpl.npz, as AMASS ships them): each sequence's dmpls drive them",
    )
    m.add_argument(
        "--skinning",
        choices=("lbs", "dqs"),
        default=None,
        help="lbs: linear blend skinning (default); dqs: dual-quaternion skinning, for the vertices and "
        "extra vertex joints (see docs/skinning.md)",
    )
    o = p.add_argument_group("what to write")
    o.add_argument(
        "--recipe",
        choices=sorted(RECIPES),
        default=None,
        help="preset options; 'humanml3d' = --model-type smplh --gender humanml3d --num-betas 10 --fps 20 "
        "--resample stride --axes xzy --format npy (explicit options win)",
    )
    o.add_argument("--joints", action="store_true", help="write joints (always done; the default)")
    o.add_argument("--vertices", action="store_true", default=None, help="also write mesh vertices (npz only)")
    o.add_argument(
        "--extra-joints",
        action="store_true",
        default=None,
        help="keep the extra vertex joints and landmarks after the skeleton joints",
    )
    o.add_argument("--num-joints", type=_count, default=None, help="keep the first N joints (HumanML3D: 22)")
    o.add_argument("--fps", type=_positive_float, default=None, help="output frame rate (default: the source's)")
    o.add_argument(
        "--resample",
        choices=METHODS,
        default=None,
        help="interp: slerp to exactly --fps (default); nearest: nearest frames; stride: every "
        "int(fps/target)-th frame (HumanML3D)",
    )
    o.add_argument("--axes", default=None, help="output axes, e.g. xzy (swap y and z, HumanML3D) or x,-z,y")
    o.add_argument(
        "--dtype",
        choices=("float32", "float16", "float64"),
        default=None,
        help="stored dtype (default: float32)",
    )
    o.add_argument(
        "--format",
        choices=("npz", "npy"),
        default=None,
        help="npz: joints, vertices and metadata (default); npy: joints only (HumanML3D)",
    )
    o.add_argument("--compress", action="store_true", default=None, help="compressed .npz")
    o.add_argument(
        "--exclude",
        action="append",
        default=None,
        metavar="GLOB",
        help="leave out matching files (default: shape.npz); repeatable",
    )
    r = p.add_argument_group("how to run")
    r.add_argument(
        "--workers",
        type=_count,
        default=None,
        help="worker processes (default: all CPUs; 0: in this process); with --ray: local CPUs",
    )
    r.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help="run as Ray tasks: a local cluster without ADDRESS, else ray.init(address=ADDRESS) (pip install ray)",
    )
    r.add_argument(
        "--backend",
        choices=("auto", "numpy", "torch"),
        default=None,
        help="evaluation backend (default auto = numpy, the fastest on a CPU)",
    )
    r.add_argument(
        "--batch-frames",
        type=_count,
        default=None,
        help="frames per forward call (default: 1024 with numpy, 4096 with torch)",
    )
    r.add_argument("--overwrite", action="store_true", help="recompute outputs that exist")
    r.add_argument("--quiet", "--no-progress", dest="quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run_process)


def run_process(args: argparse.Namespace) -> int:
    import warnings

    from smplcore.motion.process import (
        DEFAULT_EXCLUDE,
        EXIT_DISK_FULL,
        DiskFullError,
        OutputSizeWarning,
        options_from_recipe,
        process_tree,
    )
    from smplcore.motion.process import run as run_module

    if args.backend == "torch":
        from smplcore.motion.models import resolve_backend

        resolve_backend("torch")  # without PyTorch: one line and exit 2, before any file is tried
    options = options_from_recipe(
        args.recipe,
        model_path=args.model_path,
        model_type=args.model_type,
        gender=args.gender,
        ext=args.ext,
        num_betas=args.num_betas,
        fps=args.fps,
        resample=args.resample,
        vertices=args.vertices,
        extra_joints=args.extra_joints,
        num_joints=args.num_joints,
        axes=args.axes,
        dtype=args.dtype,
        format=args.format,
        compress=args.compress,
        backend=args.backend,
        chunk=args.batch_frames or None,
        dmpl_path=args.dmpl,
        skinning=args.skinning,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("always", OutputSizeWarning)
        warnings.showwarning = _size_warning_as_one_line(warnings.showwarning)
        try:
            summary = process_tree(
                args.input,
                args.output,
                options,
                workers=args.workers,
                ray_address=args.ray,
                overwrite=args.overwrite,
                exclude=args.exclude or DEFAULT_EXCLUDE,
                progress=not args.quiet,
                check=False,
                warn_bytes=run_module.DEFAULT_WARN_BYTES,
            )
        except KeyboardInterrupt:
            print("smplcore process: interrupted; finished outputs are kept, rerun to resume", file=sys.stderr)
            return 130
        except DiskFullError as exc:
            print(f"smplcore process: {exc}", file=sys.stderr)
            return EXIT_DISK_FULL
    print(summary.format())
    if summary.stopped:
        print(f"smplcore process: stopped: {summary.stopped}; free some space and rerun to resume", file=sys.stderr)
    return summary.exit_code


def _size_warning_as_one_line(show):
    """``warnings.showwarning`` that prints OutputSizeWarning and ShapeSpaceWarning as one line (other warnings
    as ``show`` does)."""
    from smplcore.motion.process import OutputSizeWarning
    from smplcore.motion.sequence import ShapeSpaceWarning

    def showwarning(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001, ANN202
        if issubclass(category, (OutputSizeWarning, ShapeSpaceWarning)):
            print(f"smplcore process: warning: {message}", file=sys.stderr, flush=True)
        else:
            show(message, category, filename, lineno, file, line)

    return showwarning
