"""``smplcore export`` for the interchange formats: rigged USD / USDZ, ``.smpl`` and the SMPL-X Blender add-on npz.

Chosen by ``--format usd|usdz|smpl|blender-npz`` or by the output suffix (``.usd``, ``.usda``, ``.usdc``,
``.usdz``, ``.smpl``; a ``.npz`` output needs ``--format blender-npz``). Examples::

    smplcore export walk.npz -o walk.usdz                       # rigged, animated USDZ on the open model
    smplcore export walk.npz -o walk.usd --model-path models/ --model-type smplx --pose-correctives
    smplcore export walk.npz -o walk.smpl                       # AMASS -> .smpl (no model needed)
    smplcore export walk.smpl -o walk.usdc                      # .smpl is an input too
    smplcore export fit.npz -o fit.smpl --model-path models/ --model-type smplx   # a fit result / parameter set
    smplcore export walk.npz -o blender.npz --format blender-npz --up z --model-path models/ --model-type smplx
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path
from typing import Any

INTERCHANGE = {
    "usd": (".usd", ".usda", ".usdc"),
    "usdz": (".usdz",),
    "smpl": (".smpl",),
    "blender-npz": (".npz",),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the interchange formats on ``smplcore export``."""
    names = sorted(INTERCHANGE)
    existing = next((a for a in parser._actions if "--format" in a.option_strings), None)
    if existing is None:
        parser.add_argument(
            "--format",
            choices=names,
            default=None,
            help="usd (.usd/.usda/.usdc), usdz, smpl or blender-npz (.npz the SMPL-X Blender add-on imports); "
            "default: from the suffix of OUT (OUT without a suffix gets the format's)",
        )
    else:  # another exporter's --format (the suffix formats): these are more choices of it
        existing.choices = [*(existing.choices or ()), *(n for n in names if n not in (existing.choices or ()))]
        existing.help = f"{existing.help}; also {', '.join(names)} (blender-npz: the SMPL-X Blender add-on's .npz)"
    _add_once(
        parser,
        "--pose-correctives",
        action="store_true",
        help=".usd/.usdz: write the model's pose correctives as blend shapes (the full model; a larger file)",
    )
    _add_once(
        parser,
        "--shape-blend-shapes",
        action="store_true",
        help=".usd/.usdz: add the shape components as blend shapes at weight 0",
    )
    _add_once(
        parser,
        "--unit-weights",
        action="store_true",
        help=".usd/.usdz: blend-shape weights in [0, 1] (signed shapes as +/- pairs), for Blender's shape keys",
    )
    _add_once(
        parser,
        "--up",
        choices=("y", "z"),
        default="y",
        help="blender-npz: y (the model's frame; import with anim_format SMPL-X) or z (like AMASS; anim_format AMASS)",
    )


def _add_once(parser: argparse.ArgumentParser, flag: str, *, help: str, **kwargs: Any) -> None:
    """Add ``flag``, or, when another exporter already has it (e.g. FBX's ``--pose-correctives``, the same
    switch), say in its help that it applies here too."""
    existing = next((a for a in parser._actions if flag in a.option_strings), None)
    if existing is None:
        parser.add_argument(flag, help=help, **kwargs)
    else:
        existing.help = f"{existing.help}; {help}"


def format_of(args: argparse.Namespace) -> str | None:
    """The interchange format ``args`` ask for, or None for the other exporters (OBJ, PLY, glTF, BVH, ...)."""
    suffix = Path(args.output).suffix.lower()
    chosen = getattr(args, "format", None)
    if chosen in INTERCHANGE:
        if not suffix:  # OUT without a suffix gets the format's
            args.output = Path(args.output).with_suffix(INTERCHANGE[chosen][0])
            return chosen
        if suffix not in INTERCHANGE[chosen]:
            raise ValueError(
                f"-o/--output: --format {chosen} writes {'/'.join(INTERCHANGE[chosen])} files, got {args.output}"
            )
        return chosen
    return next((name for name, s in INTERCHANGE.items() if suffix in s and name != "blender-npz"), None)


def _read_source(args: argparse.Namespace) -> Any:
    from smplcore.export.cli import _count, _frame_slice, _slice_params
    from smplcore.export.inputs import load_input
    from smplcore.motion import Motion

    source = load_input(args.input, fps=args.fps)
    frames = _frame_slice(args.frames)
    if frames is None:
        return source
    total = source.num_frames if isinstance(source, Motion) else _count(source)
    if not range(total)[frames]:
        raise ValueError(f"--frames: {args.frames} selects no frame; {args.input} has {total} frame(s) (0:{total})")
    if isinstance(source, Motion):
        return source.slice(frames.start or 0, frames.stop, frames.step or 1)
    return _slice_params(source, frames)


def run_interchange(args: argparse.Namespace, fmt: str) -> int:
    """Write the interchange format ``fmt``; prints what was written and what the format could not hold."""
    from smplcore.export.cli import _build_model, _count, _progress_bar
    from smplcore.motion import Motion

    out = Path(args.output)
    if args.texture is not None and fmt not in ("usd", "usdz"):
        raise ValueError(f"--texture: a {fmt} file holds no texture")
    source = _read_source(args)
    reported: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if fmt in ("usd", "usdz"):
            from smplcore.export.usd import save_usd

            model = _build_model(args, source)
            if model.skinning == "dqs":
                warnings.warn("--skinning dqs: UsdSkel skins are linear blend skinning (posed by LBS)", stacklevel=2)
            if args.colors != "none":
                warnings.warn("--colors: vertex colours are not written to USD", stacklevel=2)
            count = source.num_frames if isinstance(source, Motion) else _count(source)
            bar = _progress_bar(count * (2 + int(args.pose_correctives)), args.no_progress or count < 100)
            try:
                report = save_usd(
                    out,
                    model,
                    source,
                    fps=args.fps,
                    pose_correctives=args.pose_correctives,
                    shape_blend_shapes=args.shape_blend_shapes,
                    unit_weights=args.unit_weights,
                    texture=args.texture,
                    progress=None if bar is None else bar.update,
                )
            finally:
                if bar is not None:
                    bar.close()
            message, reported = report.summary(), report.warnings
        elif fmt == "smpl":
            from smplcore.export.smplfile import read_smpl, save_smpl

            model = None if isinstance(source, Motion) else _build_model(args, source)
            save_smpl(out, source, model, fps=args.fps)
            data = read_smpl(out)
            message = (
                f"wrote {out} (smpl, {out.stat().st_size / 1e3:.1f} kB): {data.num_frames} frame(s) at "
                f"{data.fps or 0:g} fps, {data.model_type}"
            )
        else:
            message = _write_blender(args, source, out)
    for w in caught:
        if str(w.message) not in reported:
            print(f"warning: {w.message}", file=sys.stderr)
    print(message)
    return 0


def _write_blender(args: argparse.Namespace, source: Any, out: Path) -> str:
    from smplcore.export.cli import _build_model
    from smplcore.export.smplfile import _params_motion, save_blender_npz
    from smplcore.motion import Motion

    model = None
    if not isinstance(source, Motion) or args.up == "z":
        model = _build_model(args, source)
    motion = source if isinstance(source, Motion) else _params_motion(model, source, args.fps)
    save_blender_npz(out, motion, up=args.up, model=model)
    fmt = "AMASS" if args.up == "z" else "SMPL-X"
    return (
        f"wrote {out} (SMPL-X Blender add-on npz, {out.stat().st_size / 1e3:.1f} kB): {motion.num_frames} frame(s) "
        f"at {motion.fps:g} fps; import it with the add-on's Add Animation, anim_format {fmt}"
    )
