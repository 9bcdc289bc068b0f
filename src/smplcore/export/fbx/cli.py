"""The FBX options of ``smplcore export`` (kept here so the command's module only registers and dispatches)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from smplcore.export.animation import Animation, ExportReport, Progress


def add_fbx_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--fbx-unit``, ``--up-axis``, ``--input-up-axis``, ``--root-bone`` and ``--pose-correctives``."""
    group = parser.add_argument_group(".fbx options")
    group.add_argument(
        "--fbx-unit",
        choices=("cm", "m"),
        default="cm",
        help=".fbx: values in centimetres (default; FBX's and Unreal's unit) or metres; either imports at "
        "the same size",
    )
    group.add_argument(
        "--up-axis",
        choices=("y", "z"),
        default="y",
        help=".fbx: Y up (default, SMPL's frame; Unity, Maya) or Z up (Blender, Unreal, 3ds Max)",
    )
    group.add_argument(
        "--input-up-axis",
        choices=("y", "z"),
        default="y",
        help=".fbx: up axis of the input's world: y (default, SMPL's) or z (AMASS motions: the body then "
        "stands up in the file)",
    )
    group.add_argument(
        "--root-bone",
        default=None,
        metavar="NAME",
        help=".fbx: add a bone NAME at the origin above the pelvis (e.g. 'root', as Unreal expects)",
    )
    group.add_argument(
        "--pose-correctives",
        action="store_true",
        help=".fbx: export the pose-corrective blend shapes with per-frame weights (exact body; many keys)",
    )


def write_fbx(
    args: argparse.Namespace, out: Path, model: Any, anim: Animation, progress: Progress | None = None
) -> ExportReport:
    """Run :func:`smplcore.export.save_fbx` with the command's options (``--morph-targets``: shape keys)."""
    from smplcore.export import weight_colors
    from smplcore.export.fbx import save_fbx

    return save_fbx(
        out,
        model,
        anim,
        unit=args.fbx_unit,
        up_axis=args.up_axis,
        input_up_axis=args.input_up_axis,
        root_bone=args.root_bone,
        shape_keys=args.morph_targets,
        pose_correctives=args.pose_correctives,
        vertex_colors=weight_colors(anim.weights) if args.colors == "weights" else None,
        texture=args.texture,
        progress=progress,
    )
