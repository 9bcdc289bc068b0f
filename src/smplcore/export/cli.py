"""``smplcore export``: a parameter set or a motion to a mesh (OBJ/PLY), a rigged animation (glTF
binary, FBX) or skeleton motion (BVH). Registered by :mod:`smplcore.cli`.

Examples::

    smplcore export walk.npz -o walk.glb                  # AMASS-style motion on the open model
    smplcore export walk.npz -o walk.bvh --bvh-scale 100  # BVH in centimetres
    smplcore export walk.npz -o frame10.obj --frame 10 --colors weights
    smplcore export walk.npz -o walk.glb --texture skin.png    # UVs (open model, SMPL-X) + a texture
    smplcore export walk.npz -o walk.glb --model-path models/ --model-type smplh
    smplcore export params.npz -o body.glb                # one parameter set (betas, body_pose, ...)
    smplcore export walk.npz -o walk.glb --engine unreal  # root bone, centimetres, feet on the ground
    smplcore export walk.npz -o avatar.vrm                # VRM 1.0 avatar (T-pose) of the motion's body
    smplcore export walk.npz -o walk.vrma                 # VRM animation clip any VRM avatar plays
    smplcore export walk.npz -o walk.fbx --up-axis z --root-bone root   # FBX for Unreal (centimetres)
    smplcore export walk.npz -o walk.usdz                 # rigged USDZ; also .usd/.smpl (see export/cli_usd.py)
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.cli_options import model_file_options

FORMATS = (".obj", ".ply", ".glb", ".bvh", ".fbx", ".vrm", ".vrma")
_HAND_BLOCKS = ("left_hand_pose", "right_hand_pose", "hand_pose")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``smplcore export``."""
    parser = subparsers.add_parser(
        "export",
        help="write a posed mesh (.obj/.ply), a rigged animation (.glb) or skeleton motion (.bvh)",
        description="Export a parameter set or a motion sequence. INPUT is an AMASS-style motion .npz "
        "(poses, trans, betas, gender, mocap_framerate) or a parameter set (.npz / .json with model keyword "
        "arrays such as betas, global_orient, body_pose, transl; one row or one row per frame). "
        "The output format follows the suffix of OUT. Without --model-path the packaged open model "
        "is used.",
    )
    parser.add_argument("input", type=Path, metavar="INPUT", help="motion or parameter file (.npz / .json)")
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        metavar="OUT",
        help="output file: .obj, .ply (one posed frame), .glb or .fbx (rigged + animated), .bvh, .vrm (VRM 1.0 "
        "avatar) or .vrma (VRM animation)",
    )
    parser.add_argument(
        "--format",
        default=None,
        choices=[f.lstrip(".") for f in FORMATS],
        help="output format (default: from the suffix of OUT; OUT without a suffix gets this one)",
    )
    parser.add_argument("--model-path", default=None, help="model file or folder (default: the open model)")
    parser.add_argument(
        "--model-type",
        default=None,
        help="smpl, smplh, smplx, mano, flame or open (default: open without --model-path, else from the file)",
    )
    parser.add_argument("--gender", default=None, help="model gender (default: the motion's, else neutral)")
    model_file_options(
        parser,
        use_pca_default="no for motions, which store axis-angle; for parameter sets, yes unless the hand poses "
        "have 45 values",
    )
    parser.add_argument(
        "--dmpl",
        default=None,
        metavar="FILE",
        help="DMPL soft-tissue blend shapes (dmpl.npz) driven by the input's dmpls: baked into .obj/.ply, "
        "animated morph targets in .glb",
    )
    parser.add_argument(
        "--num-betas",
        type=int,
        default=None,
        help="shape coefficients to use (default: as many as the input has)",
    )
    parser.add_argument(
        "--fps",
        type=float,
        default=None,
        help="frame rate (default: the motion's, 30 for parameter sets; required for a motion that states none)",
    )
    parser.add_argument(
        "--frames",
        default=None,
        metavar="START:STOP[:STEP]",
        help="export only these frames of a sequence (a STEP > 1 divides the frame rate)",
    )
    parser.add_argument("--frame", type=int, default=0, help=".obj/.ply: the frame to write (default: 0)")
    parser.add_argument(
        "--skinning",
        choices=("lbs", "dqs"),
        default="lbs",
        help=".obj/.ply: lbs (linear blend skinning, default) or dqs (dual-quaternion skinning) for the posed "
        "mesh; a .glb rig is always skinned by LBS in viewers (glTF has no DQS), see docs/skinning.md",
    )
    parser.add_argument(
        "--colors",
        choices=("none", "weights"),
        default="none",
        help=".obj/.ply/.glb/.fbx: per-vertex colours from the skinning weights (default: none)",
    )
    parser.add_argument(
        "--texture",
        default=None,
        metavar="FILE",
        help=".obj/.glb/.fbx/.vrm: image drawn through the model's UV map (the open model, SMPL-X; the UVs are written "
        "whenever the model has them), or 'uv-grid' for a generated grid that shows the mapping",
    )
    parser.add_argument(
        "--morph-targets",
        action="store_true",
        help=".glb/.fbx: add shape (and expression) components as morph targets (FBX: blend shapes)",
    )
    parser.add_argument(
        "--influences",
        type=int,
        choices=(4, 8),
        default=4,
        help=".glb: skinning weights kept per vertex (default: 4, what every viewer reads)",
    )
    parser.add_argument(
        "--engine",
        choices=("unreal", "unity"),
        default=None,
        help=".glb: game-engine conventions (a root bone, Unreal in centimetres, feet on the ground, 4 "
        "influences, morph weights every frame); default: the exact export",
    )
    parser.add_argument(
        "--unit-scale",
        type=float,
        default=None,
        help=".glb with --engine: lengths multiplier (default: 100 for unreal, 1 for unity)",
    )
    parser.add_argument(
        "--bvh-scale",
        type=float,
        default=1.0,
        help=".bvh: length unit multiplier; 1 = metres (default), 100 = centimetres",
    )
    parser.add_argument("--euler", default="ZYX", help=".bvh: rotation channel order (default: ZYX)")
    from smplcore.export.fbx.cli import add_fbx_options

    add_fbx_options(parser)
    hands = parser.add_mutually_exclusive_group()
    hands.add_argument(
        "--flat-hand-mean",
        dest="flat_hand_mean",
        action="store_true",
        default=None,
        help="hand poses are absolute (default for motions, which AMASS stores that way)",
    )
    hands.add_argument(
        "--no-flat-hand-mean",
        dest="flat_hand_mean",
        action="store_false",
        help="hand poses are relative to the model's mean hand pose (smplx's default)",
    )
    parser.add_argument("--no-progress", "--quiet", dest="no_progress", action="store_true", help="no progress bar")
    from smplcore.export.cli_usd import add_arguments  # USD / USDZ, .smpl, the Blender add-on npz

    add_arguments(parser)
    parser.set_defaults(run=run)


def _frame_slice(text: str | None) -> slice | None:
    if not text:
        return None
    try:
        parts = [int(p) if p.strip() else None for p in text.split(":")]
    except ValueError:
        raise ValueError(f"--frames: expected START:STOP[:STEP], got {text!r}") from None
    if not 1 <= len(parts) <= 3 or (len(parts) == 3 and parts[2] is not None and parts[2] < 1):
        raise ValueError(f"--frames: expected START:STOP[:STEP] with STEP >= 1, got {text!r}")
    return slice(*parts) if len(parts) > 1 else slice(parts[0], None)


def _slice_params(params: dict[str, Any], frames: slice) -> dict[str, Any]:
    arrays = {k: np.asarray(v) for k, v in params.items() if not isinstance(v, str)}
    count = max((v.shape[0] for v in arrays.values() if v.ndim > 1), default=1)
    out = dict(params)
    for k, v in arrays.items():
        if v.ndim > 1 and v.shape[0] == count and k != "betas":
            out[k] = v[frames]
    if frames.step and frames.step > 1 and "fps" in out:
        out["fps"] = float(np.asarray(out["fps"]).reshape(-1)[0]) / frames.step
    return out


def _build_model(args: argparse.Namespace, source: Any) -> Any:
    from smplcore import BodyModel
    from smplcore.motion import Motion

    is_motion = isinstance(source, Motion)
    options: dict[str, Any] = {}
    if is_motion:
        betas = np.asarray(source.betas).reshape(-1)
        gender = args.gender or source.gender or "neutral"
        options.update(use_pca=False, flat_hand_mean=True if args.flat_hand_mean is None else args.flat_hand_mean)
        if source.expression is not None:
            options["num_expression_coeffs"] = int(np.asarray(source.expression).shape[-1])
    else:
        betas = np.asarray(source.get("betas", np.zeros(10)))
        betas = betas.reshape(-1) if betas.ndim < 2 else betas[0]
        gender = args.gender or str(source.get("gender", "neutral"))
        hand = next((np.asarray(source[b]) for b in _HAND_BLOCKS if b in source), None)
        if hand is not None:
            width = hand.reshape(-1).shape[0] if hand.ndim < 2 else int(np.prod(hand.shape[1:]))
            options.update(use_pca=width != 45, **({"num_pca_comps": width} if width != 45 else {}))
        options["flat_hand_mean"] = bool(args.flat_hand_mean)
        if "expression" in source:
            expr = np.asarray(source["expression"])
            options["num_expression_coeffs"] = int(expr.shape[-1]) if expr.ndim else 1
    options["num_betas"] = args.num_betas if args.num_betas is not None else max(int(betas.shape[0]), 1)
    use_pca = getattr(args, "use_pca", None)
    if use_pca is not None:
        options["use_pca"] = bool(use_pca)
        if not use_pca:
            options.pop("num_pca_comps", None)
    if getattr(args, "dmpl", None):
        options["dmpl_path"] = args.dmpl
    options["skinning"] = getattr(args, "skinning", "lbs")
    if args.model_path is None and args.model_type in (None, "open"):
        return BodyModel(model_type="open", gender=gender, **options)  # it has three genders too
    ext = getattr(args, "ext", None)
    return BodyModel(args.model_path, model_type=args.model_type, gender=gender, ext=ext, **options)


def _progress_bar(total: int, disable: bool):
    try:
        from tqdm import tqdm
    except ImportError:  # the cli extra is not installed: no bar
        return None
    return tqdm(
        total=total,
        unit="frame",
        desc="export",
        disable=True if disable else None,
        file=sys.stderr,
        leave=False,
    )


def run(args: argparse.Namespace) -> int:
    from smplcore.export import save_bvh, save_glb, save_mesh, weight_colors
    from smplcore.export.animation import load_input, prepare_animation
    from smplcore.export.cli_usd import format_of, run_interchange
    from smplcore.motion import Motion

    interchange = format_of(args)  # USD / USDZ, .smpl, the Blender add-on npz
    if interchange is not None:
        return run_interchange(args, interchange)
    out = Path(args.output)
    fmt = getattr(args, "format", None)
    if fmt and not out.suffix:
        out = out.with_suffix(f".{fmt}")
    elif fmt and out.suffix.lower() != f".{fmt}":
        raise ValueError(f"--format {fmt}: the output {str(out)!r} has another suffix; use .{fmt} or drop --format")
    suffix = out.suffix.lower()
    if suffix not in FORMATS:
        expected = ", ".join(FORMATS + (".usd", ".usda", ".usdc", ".usdz", ".smpl"))
        raise ValueError(f"-o/--output: unsupported suffix {out.suffix!r}; expected one of {expected}")
    if (args.engine is not None or args.unit_scale is not None) and suffix != ".glb":
        raise ValueError(f"--engine/--unit-scale: engine conventions apply to .glb files, not {out.suffix!r}")
    if args.texture is not None and suffix not in (".obj", ".glb", ".fbx", ".vrm"):
        raise ValueError(
            f"--texture: textures are written to .obj, .glb and .fbx files (and .vrm avatars), not {out.suffix!r}"
        )
    source = load_input(args.input, fps=args.fps)  # the rate of a motion that states none
    frames = _frame_slice(args.frames)
    if frames is not None:
        total = source.num_frames if isinstance(source, Motion) else _count(source)
        if not range(total)[frames]:
            what = "motion" if isinstance(source, Motion) else "parameter set"
            raise ValueError(
                f"--frames: {args.frames} selects no frame; the {what} {args.input} has {total} frame(s) (0:{total})"
            )
        source = (
            source.slice(frames.start or 0, frames.stop, frames.step or 1)
            if isinstance(source, Motion)
            else _slice_params(source, frames)
        )

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = _build_model(args, source)
        _warn_unused_dmpls(source, model, suffix)
        if model.skinning == "dqs" and suffix == ".glb":
            warnings.warn(
                "--skinning dqs: glTF skins are linear blend skinning, so the .glb rig holds the LBS weights "
                "and viewers pose it by LBS; for dual-quaternion-skinned vertices write .obj/.ply frames or "
                "use 'smplcore process --vertices --skinning dqs'",
                stacklevel=2,
            )
        elif model.skinning == "dqs" and suffix == ".bvh":
            warnings.warn("--skinning dqs: a .bvh holds the skeleton only; skinning does not change it", stacklevel=2)
        if suffix in (".obj", ".ply"):
            message = _write_mesh(args, model, source, out, save_mesh, weight_colors)
            report_warnings: list[str] = []
        else:
            count = source.num_frames if isinstance(source, Motion) else _count(source)
            passes = (
                2 + (suffix in (".glb", ".fbx") and bool(model.has_pose_correctives)) - (suffix in (".vrm", ".vrma"))
            )
            bar = _progress_bar(count * passes, args.no_progress or count < 100)
            update = None if bar is None else bar.update
            try:
                anim = prepare_animation(model, source, fps=args.fps, progress=update)
                if suffix == ".glb":
                    colors = weight_colors(model.skinning_weights) if args.colors == "weights" else None
                    report = save_glb(
                        out,
                        model,
                        anim,
                        morph_targets=args.morph_targets,
                        influences=args.influences,
                        vertex_colors=colors,
                        texture=args.texture,
                        progress=update,
                        engine=args.engine,
                        unit_scale=args.unit_scale,
                    )
                elif suffix in (".vrm", ".vrma"):
                    from smplcore.export.vrm import save_vrm, save_vrma

                    report = (
                        save_vrm(out, model, anim, texture=args.texture)
                        if suffix == ".vrm"
                        else save_vrma(out, model, anim)
                    )
                elif suffix == ".fbx":
                    from smplcore.export.fbx.cli import write_fbx

                    report = write_fbx(args, out, model, anim, progress=update)
                else:
                    report = save_bvh(out, model, anim, scale=args.bvh_scale, euler=args.euler, progress=update)
            finally:
                if bar is not None:
                    bar.close()
            message = report.summary()
            report_warnings = report.warnings
    for w in caught:
        text = str(w.message)
        if text not in report_warnings:
            print(f"warning: {text}", file=sys.stderr)
    print(message)
    return 0


def _warn_unused_dmpls(source: Any, model: Any, suffix: str) -> None:
    """A motion's soft tissue (``dmpls``) is used only with ``--dmpl``: say so instead of dropping it silently."""
    dmpls = source.get("dmpls") if isinstance(source, dict) else getattr(source, "dmpls", None)
    used = int(getattr(model, "num_dmpls", 0)) > 0
    if dmpls is None or used or suffix == ".bvh" or not np.any(np.asarray(dmpls)):
        return
    warnings.warn(
        f"dmpls: the input has DMPL soft-tissue coefficients ({np.shape(dmpls)[-1]} per frame) that are not "
        "used; add --dmpl FILE (AMASS's DMPL download, dmpls/<gender>/model.npz) to write the soft tissue",
        stacklevel=2,
    )


def _count(params: dict[str, Any]) -> int:
    sizes = [
        np.asarray(v).shape[0]
        for k, v in params.items()
        if not isinstance(v, str) and np.asarray(v).ndim > 1 and k != "betas"
    ]
    return max(sizes, default=1)


def _write_mesh(
    args: argparse.Namespace, model: Any, source: Any, out: Path, save_mesh: Any, weight_colors: Any
) -> str:
    from smplcore.model.params import fit_width
    from smplcore.motion import Motion
    from smplcore.uv import model_uv

    if isinstance(source, Motion):
        total = source.num_frames
        params = source.model_params(model.model_type, model.skeleton_joint_names, model.num_betas)
        if model.num_dmpls and source.dmpls is not None:
            params["dmpls"] = fit_width("dmpls", np.asarray(source.dmpls), model.num_dmpls)
    else:
        total = _count(source)
        allowed = set(model.pose_blocks) | {"betas", "expression", "transl"} | ({"dmpls"} if model.num_dmpls else set())
        params = {k: np.asarray(v) for k, v in source.items() if k in allowed}
    k = args.frame if args.frame >= 0 else total + args.frame
    if not 0 <= k < total:
        raise ValueError(f"--frame: {args.frame} is outside the {total} frame(s) of {args.input}")
    frame = {}
    for name, value in params.items():
        value = np.asarray(value)
        if name == "betas":
            value = value.reshape(1, -1) if value.ndim < 2 else value[:1]
            value = fit_width("betas", value, model.num_betas)
        elif value.ndim > 1 and value.shape[0] == total and total > 1:
            value = value[k : k + 1]
        frame[name] = value
    output = model(**frame)
    colors = weight_colors(model.skinning_weights) if args.colors == "weights" else None
    uv = model_uv(model) if out.suffix.lower() == ".obj" else None
    if args.texture is not None and uv is None:
        raise ValueError(f"--texture: the {model.model_type} model has no UV map")
    textured = {"uv": uv, "texture": args.texture} if uv is not None else {}
    path = save_mesh(out, output.vertices[0], model.faces, vertex_colors=colors, **textured)
    return (
        f"wrote {path} ({suffix_name(path)}, {path.stat().st_size / 1e3:.1f} kB): frame {k} of {total}, "
        f"{output.vertices.shape[1]} vertices"
    )


def suffix_name(path: Path) -> str:
    return path.suffix.lower().lstrip(".")
