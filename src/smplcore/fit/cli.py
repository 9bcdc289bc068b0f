"""``smplcore fit INPUT -o OUT``: keypoints, joints or another model's motion to an AMASS-style ``.npz``.

One input writes one file; a folder of inputs writes one file per input under OUT (a folder), with the
motion pipeline's atomic writes (a killed run leaves complete files or none), resumable (existing
outputs are kept unless ``--overwrite``), ``--workers`` processes, bad inputs reported and skipped
(exit status 1), fits that did not converge listed in the summary and in ``OUT/fit_manifest.json``.
"""

from __future__ import annotations

import argparse
import errno
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.fit.cli_types import (
    _extrinsics,
    _floats,
    _person,
    _positive,
    _positive_floats,
    _positive_int,
    _skeleton,
    _units,
    _weights,
)

EPILOG = """\
examples:
  smplcore fit openpose_frames/ -o fit.npz --focal 1000 --center 960,540
  smplcore fit person_keypoints.json -o fit.npz                # COCO: each image's size, focal = diagonal
  smplcore fit openpose_frames/ -o fit.npz --image-size 1920,1080 --estimate-focal
  smplcore fit openpose_frames/ -o fit.npz --image-size 1920,1080 --vposer V02_05/
  smplcore fit joints.npy -o fit.npz --convention coco17        # or --joint-names pelvis,left_hip,...
  smplcore fit clip.bvh.gz -o fit.npz                           # skeleton and units detected (--skeleton, --units)
  smplcore fit smplh_motion.npz -o smplx.npz --model-type smplx --model-path models/ --source-model-path models/
  smplcore fit inputs/ -o fits/ --image-size 1920,1080 --workers 2
  smplcore fit inputs/ -o fits/ --image-size 1920,1080 --ray          # Ray tasks (local, or --ray auto)
Exit status: 0 all fitted, 1 inputs skipped (bad input), 2 bad arguments. See docs/fit.md."""

SUFFIXES = (".json", ".npy", ".npz", ".bvh", ".bvh.gz")
MANIFEST = "fit_manifest.json"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``smplcore fit``."""
    p = subparsers.add_parser(
        "fit",
        help="fit a body model to 2D keypoints, 3D joints or another model's motion; write AMASS-style .npz",
        description="Fit model parameters to INPUT (an OpenPose JSON folder, a COCO keypoint .json, a .npy of "
        "joints (T, n, 3), a BVH motion capture (.bvh, .bvh.gz), an AMASS-style .npz of another model, or a folder "
        "of such inputs) and write an AMASS-style .npz that smplcore export / process read.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("input", type=Path, metavar="INPUT")
    p.add_argument("-o", "--output", type=Path, required=True, help="output .npz (a folder for a folder of inputs)")
    p.add_argument("--model-type", default="open", help="model to fit: open (default), smpl, smplh, smplx")
    p.add_argument("--model-path", default=None, help="model file or folder (default: the open model)")
    p.add_argument(
        "--gender", default="neutral",
        help="the fitted model's gender: neutral (default), male or female (the open model has all three); a "
        "converted motion's source model takes the gender its file names",
    )  # fmt: skip
    p.add_argument("--source-model-path", default=None, help="conversion: the source motion's model (default: open)")
    p.add_argument("--convention", default=None, help="keypoint/joint convention (default: the reader's)")
    p.add_argument("--joint-names", default=None, help=".npy joints: the model joint names, comma-separated")
    p.add_argument("--joint-weights", type=_weights, default=None,
                   help=".npy joints: a weight per joint, comma-separated (0 leaves a joint out)")  # fmt: skip
    p.add_argument(
        "--skeleton", type=_skeleton, default=None, metavar="NAME",
        help="BVH: the skeleton map (default: detected from the joint names); .npy: read the points as this keypoint "
        "skeleton. Known: cmu_daz, cmu_mb, cmu_max, fair, h36m17, h36m32, mediapipe33, openpose25",
    )  # fmt: skip
    p.add_argument(
        "--units", type=_units, default=None, metavar="UNITS",
        help="BVH / .npy joints: cm, m, mm, in, cmu (CMU ASF, 0.0254/0.45 m) or metres per unit (default: told "
        "from the leg length, and said; centimetres are converted with a message)",
    )  # fmt: skip
    p.add_argument("--focal", type=_positive_floats, default=None, help="2D: focal length f or fx,fy (pixels)")
    p.add_argument("--center", type=_floats, default=None, help="2D: principal point cx,cy (pixels)")
    p.add_argument(
        "--extrinsics", type=_extrinsics, default=None, metavar="MATRIX",
        help="2D: the camera's world-to-camera transform [R | t] (OpenCV axes: x right, y down, z forward), 12 or "
        "16 numbers row by row or a .npy / text file of them; the fit is written in that world. Default: a level "
        "camera, Y up, the lowest point of the bodies on the ground y = 0 (the output records the extrinsics)",
    )  # fmt: skip
    p.add_argument(
        "--image-size", type=_positive_floats, default=None,
        help="2D: W,H; principal point at the centre; without --focal the focal length is the image diagonal",
    )  # fmt: skip
    p.add_argument(
        "--estimate-focal", action=argparse.BooleanOptionalAction, default=False,
        help="2D without --focal: estimate the focal length, starting from the image diagonal (about six times "
        "the time; recovered only roughly, for wide lenses and people near the camera; see docs/fit.md)",
    )  # fmt: skip
    p.add_argument("--vposer", default=None, metavar="PATH", help="2D: VPoser v2 pose prior (V02_05/ or its .ckpt)")
    p.add_argument("--gmm", default=None, metavar="PATH", help="2D: SMPLify's gmm_08.pkl pose prior")
    p.add_argument("--fps", type=_positive, default=30.0, help="output frame rate (default 30; a BVH: its own)")
    p.add_argument(
        "--person", type=_person, default=0, metavar="N|all",
        help="OpenPose: the people are tracked over the frames; N picks track N (0, the default: the person seen in "
        "the most frames), 'all' fits every track (a row per track and frame, each track its own shape)",
    )  # fmt: skip
    p.add_argument(
        "--overlay", type=Path, default=None, metavar="PNG",
        help="2D: draw the fit of the first image / frame over --image (or a blank canvas of the image's size) "
        "through its camera, to this .png",
    )  # fmt: skip
    p.add_argument("--image", type=Path, default=None, help="2D: the photo --overlay draws on")
    p.add_argument("--smoothness", type=float, default=1e-3, help="sequences: temporal smoothness weight")
    p.add_argument(
        "--max-iter", type=_positive_int, default=None, metavar="N",
        help="the solver's iteration budget per round (default: each fit's, 25 for 2D keypoints); frames that use it "
        "all before their cost settles are reported",
    )  # fmt: skip
    p.add_argument("--workers", type=int, default=1, help="folder of inputs: processes (default 1)")
    p.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help="folder of inputs: run the fits as Ray tasks (a local instance, or ADDRESS / 'auto' for a cluster)",
    )
    p.add_argument("--overwrite", action="store_true", help="refit inputs whose output exists")
    p.add_argument("--no-progress", "--quiet", dest="no_progress", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def _check_camera(args: argparse.Namespace, source: Path) -> None:
    """Camera options that cannot work, refused before any fit (exit status 2); absurd focal lengths too."""
    from smplcore.fit.inputs import input_kind

    if args.focal is not None and args.center is None and args.image_size is None:
        raise ValueError("--focal: the principal point is needed too: add --center cx,cy or --image-size W,H")
    if args.focal is None and args.image_size is None and source.exists():
        inputs = [source] if _is_single(source) else find_inputs(source) if source.is_dir() else []
        openpose = [p for p in inputs if p.is_dir() and _safe_kind(input_kind, p) == "openpose"]
        if openpose:
            raise ValueError(
                f"camera: OpenPose keypoints ({openpose[0]}) need the camera: pass --focal f --center cx,cy, or "
                "--image-size W,H (the focal length is then the image diagonal)"
            )
    if args.focal is None:
        return
    if args.image_size is not None:
        width, height = args.image_size
    else:
        width, height = 2.0 * abs(args.center[0]), 2.0 * abs(args.center[1])  # the image around its centre
    diagonal = float(np.hypot(width, height))
    if diagonal <= 0:
        return
    for f in args.focal:
        fov = float(np.degrees(2.0 * np.arctan(diagonal / (2.0 * f))))
        text = f"--focal {f:g}: a {fov:.3g}° field of view across the {diagonal:.0f} px image diagonal"
        if fov > 170.0 or fov < 0.1:
            raise ValueError(
                f"{text}, not a camera lens; the focal length is in pixels: focal mm x image width px / sensor "
                f"width mm (about {diagonal:.0f} px for a normal lens)"
            )
        if fov > 120.0 or fov < 2.0:
            print(f"warning: {text}; is it in pixels (focal mm x image width px / sensor width mm)?", file=sys.stderr)


def _safe_kind(kind, path: Path) -> str | None:
    try:
        return kind(path)
    except (ValueError, OSError):
        return None


def _settings(args: argparse.Namespace):
    from smplcore.fit.inputs import FitSettings

    for name in ("center", "image_size"):
        value = getattr(args, name)
        if value is not None and len(value) != 2:
            raise ValueError(f"--{name.replace('_', '-')}: expected two numbers, got {value}")
    if args.focal is not None and len(args.focal) not in (1, 2):
        raise ValueError(f"--focal: expected f or fx,fy, got {args.focal}")
    names = None if args.joint_names is None else tuple(n.strip() for n in args.joint_names.split(",") if n.strip())
    for option in ("vposer", "gmm"):
        value = getattr(args, option)
        if value is not None and not Path(value).exists():
            raise ValueError(f"--{option}: {value}: no such file or folder")
    settings = FitSettings(
        model_type=args.model_type,
        model_path=args.model_path,
        gender=args.gender,
        convention=args.convention,
        joint_names=names,
        joint_weights=args.joint_weights,
        focal=args.focal,
        center=args.center,
        image_size=args.image_size,
        fps=args.fps,
        person=args.person,
        smoothness=args.smoothness,
        source_model_path=args.source_model_path,
        estimate_focal=args.estimate_focal,
        vposer=None if args.vposer is None else str(Path(args.vposer).resolve()),
        gmm=None if args.gmm is None else str(Path(args.gmm).resolve()),
        extrinsics=args.extrinsics,
        max_iter=args.max_iter,
        overlay=None if args.overlay is None else str(args.overlay),
        image=None if args.image is None else str(args.image),
        skeleton=args.skeleton,
        units=args.units,
    )
    if settings.vposer or settings.gmm:  # read once here: a bad prior file is one clear error, not one per input
        from smplcore.fit.inputs import _priors

        _priors(settings)
    return settings


def _is_single(path: Path) -> bool:
    """A file, or a folder of OpenPose output (``*_keypoints.json`` files, as OpenPose names them, only)."""
    if path.is_file():
        return True
    if not path.is_dir():
        return False
    entries = [p for p in path.iterdir() if not p.name.startswith(".")]
    return bool(entries) and all(p.is_file() and p.name.lower().endswith("_keypoints.json") for p in entries)


def find_inputs(folder: Path) -> list[Path]:
    """The inputs of a folder: files with a known suffix and sub-folders of OpenPose JSON, sorted."""
    found = []
    for p in sorted(folder.iterdir()):
        if p.name.startswith(".") or p.name == MANIFEST:
            continue
        if (p.is_file() and p.name.lower().endswith(SUFFIXES)) or (p.is_dir() and _is_single(p)):
            found.append(p)
    return found


_MODEL: dict[str, Any] = {}


def fit_one(source: str, output: str, settings: Any) -> dict[str, Any]:
    """Fit ``source`` and write ``output`` atomically; never raises for a bad input (a manifest entry)."""
    from smplcore.fit.inputs import build_model, fit_input
    from smplcore.jobs import atomic_write

    start = time.perf_counter()
    entry: dict[str, Any] = {"input": source, "output": output, "status": "skipped"}
    try:
        key = f"{settings.model_type}:{settings.model_path}:{settings.gender}"
        if key not in _MODEL:
            _MODEL[key] = build_model(settings)
        outputs, summary = fit_input(source, settings, _MODEL[key])
        arrays: dict[str, Any] = outputs  # np.savez's keywords (its stub reserves allow_pickle)
        atomic_write(Path(output), lambda fh: np.savez(fh, **arrays))
        entry.update(status="done", **summary)
    except OSError as exc:  # writing the output (inputs are read through smplcore's readers: ModelFileError)
        entry["reason"] = f"cannot write {output}: {exc.strerror or exc}"
        entry["fatal"] = exc.errno in _FATAL_WRITE
    except Exception as exc:  # noqa: BLE001 -- one bad input is reported, never fatal to the batch
        entry["reason"] = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
    entry["seconds"] = round(time.perf_counter() - start, 3)
    return entry


_SETTINGS: list[Any] = []


def _remember(settings: Any) -> None:
    """The run's settings, for :func:`_fit_item` (in this process: no other change)."""
    _SETTINGS[:] = [settings]


def _setup_worker(settings: Any) -> None:
    """A worker process: the run's settings, and one BLAS thread when threadpoolctl is installed (optional)."""
    _remember(settings)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    threadpool_limits(1)


def _fit_item(item: tuple[str, str]) -> dict[str, Any]:
    return fit_one(item[0], item[1], _SETTINGS[0])


def _dead(item: tuple[str, str], reason: str) -> dict[str, Any]:
    why = "its worker process died (out of memory? killed?)" if reason == "died" else reason
    return {"input": item[0], "output": item[1], "status": "skipped", "reason": why}


# Errors writing an output that every later output would meet too: the batch stops (finished outputs are kept).
_FATAL_WRITE = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.ENOTDIR, errno.EFBIG}


def _bar(total: int, disable: bool):
    try:
        from tqdm import tqdm
    except ImportError:  # optional
        return None
    return tqdm(total=total, unit="input", desc="fit", disable=True if disable else None, file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    settings = _settings(args)
    source, out = Path(args.input), Path(args.output)
    if not source.exists():
        raise FileNotFoundError(f"{source}: no such file or folder")
    if not source.is_dir():  # a FIFO, device or socket: refused without opening it
        from smplcore.io import open_input

        open_input(source, "an input file (.json, .npy, .npz, .bvh) or folder")[0].close()
    _check_camera(args, source)
    from smplcore.fit.inputs2d import check_overlay

    check_overlay(args.overlay, args.image, _is_single(source))
    if _is_single(source):
        if out.suffix.lower() != ".npz":
            raise ValueError(f"-o/--output: expected a .npz file for one input, got {out}")
        if out.is_dir():
            raise ValueError(f"-o/--output: {out} is a folder; one input writes one .npz file")
        _output_folder(out.parent)
        tasks = [(source, out)]
        manifest = None
    else:
        from smplcore.fit.skeleton_inputs import input_stem

        inputs = find_inputs(source)
        if not inputs:
            raise ValueError(f"{source}: no inputs (.json, .npy, .npz, .bvh(.gz) files or OpenPose folders)")
        _output_folder(out)
        tasks = [(p, out / (input_stem(p) if p.is_file() else p.name)) for p in inputs]
        tasks = [(p, o.with_name(o.name + ".npz")) for p, o in tasks]
        manifest = out / MANIFEST
    entries, todo = [], []
    for src, dst in tasks:
        if dst.exists() and not args.overwrite:
            entries.append({"input": str(src), "output": str(dst), "status": "exists"})
        else:
            todo.append((str(src), str(dst)))
    bar = _bar(len(todo), args.no_progress or len(todo) < 2)
    from smplcore.jobs import Job, remove_orphan_temporaries, run_inline, run_pool, run_ray, worker_context

    job = Job(_fit_item, _dead, _setup_worker, (settings,))
    stopping = lambda: any(e.get("fatal") for e in entries)  # noqa: E731 -- a full or read-only disk
    tick = bar.update if bar is not None else lambda: None
    try:
        if args.ray is not None and todo:
            run_ray(todo, job, args.ray, args.workers, entries.append, tick, stopping)
        elif args.workers > 1 and len(todo) > 1:
            run_pool(todo, job, args.workers, entries.append, tick, stopping, worker_context(["numpy", "smplcore.fit"]))
        else:
            run_inline(todo, Job(_fit_item, _dead, _remember, (settings,)), entries.append, tick, stopping)
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
            bar = None
        remove_orphan_temporaries({Path(d).parent for _, d in todo})
        _late_outputs(todo, entries)
        done = sum(e["status"] == "done" for e in entries)
        print(f"smplcore fit: interrupted; {done} output(s) written in this run are kept "
              "(run the same command again to fit the rest)", file=sys.stderr)  # fmt: skip
        _report(entries, manifest, quiet=True)
        return 130
    finally:
        if bar is not None:
            bar.close()
    return _report(entries, manifest, max_iter=args.max_iter)


def _output_folder(folder: Path) -> None:
    """Make ``folder`` (for the outputs) or raise ValueError saying why it cannot be."""
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"-o/--output: {folder} is a file; a folder of inputs needs an output folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"-o/--output: cannot make the folder {folder}: {exc.strerror or exc}") from None


def _rows(count: int, entry: dict[str, Any]) -> str:
    """``1 frame``, ``3 frames``, ``1 body`` (a COCO file: one row per person of each image)."""
    unit = entry.get("unit", "frames")
    return f"{count} { ({'frames': 'frame', 'bodies': 'body'}.get(unit, unit) if count == 1 else unit) }"


def _late_outputs(todo: list[tuple[str, str]], entries: list[dict[str, Any]]) -> None:
    """Entries for outputs renamed into place by a worker just before the batch stopped (no result reached us)."""
    reported = {e["input"] for e in entries}
    for source, output in todo:
        if source not in reported and Path(output).is_file():
            entries.append({"input": source, "output": output, "status": "done",
                            "note": "written just before the batch stopped"})  # fmt: skip


def _report(
    entries: list[dict[str, Any]], manifest: Path | None, quiet: bool = False, max_iter: int | None = None
) -> int:
    if quiet:  # after Ctrl-C: only the manifest of what was done
        _write_manifest(entries, manifest)
        return 130

    done = [e for e in entries if e["status"] == "done"]
    skipped = [e for e in entries if e["status"] == "skipped"]
    kept = [e for e in entries if e["status"] == "exists"]
    for e in skipped:
        print(f"skipped {e['input']}: {e['reason']}", file=sys.stderr)
    for e in done:
        if "frames" not in e:  # written just before the batch stopped: its summary never arrived
            print(f"wrote {e['output']} ({e.get('note', 'no summary')})")
            continue
        unit = e.get("error_unit", "")
        scale, shown = (1000.0, "mm") if unit == "m" else (1.0, unit)
        print(f"wrote {e['output']}: {_rows(e['frames'], e)}, mean error {e['mean_error'] * scale:.2f} {shown}")
        for note in e.get("notes", []):  # what was detected: a BVH's skeleton and units, joints in centimetres
            print(f"  {e['input']}: {note}")
        if e.get("missing"):
            print(f"  frames without a detection (filled from the nearest frame): {e['missing'][:20]}")
        if e.get("kind") == "openpose" and e.get("people", 1) > 1:
            print(f"  {e['people']} people tracked over the frames (--person N picks one, --person all fits every one)")
        if e.get("overlay"):
            print(f"  overlay: {e['overlay']}")
        if e.get("images_without_person"):
            unseen = e["images_without_person"]
            more = f" … (+{len(unseen) - 20})" if len(unseen) > 20 else ""
            print(f"  images without a person of 6 or more labelled keypoints (not in the output): "
                  f"{', '.join(unseen[:20])}{more}")  # fmt: skip
    lagging = [e for e in done if e.get("not_converged")]
    if lagging:
        budget = f"--max-iter {max_iter}" if max_iter is not None else "the default --max-iter"
        print(f"not converged: these frames used the whole iteration budget ({budget}) before the solver's "
              "stopping test was met; the mean error above says how far they got (a larger --max-iter "
              "iterates further):")  # fmt: skip
        for e in lagging:
            frames = e["not_converged"]
            more = f" … (+{len(frames) - 20})" if len(frames) > 20 else ""
            print(f"  {e['input']}: {len(frames)} of {_rows(e['frames'], e)} {frames[:20]}{more}")
    print(f"{len(done)} fitted, {len(skipped)} skipped (bad input), {len(kept)} already done, "
          f"{len(lagging)} stopped at the iteration budget")  # fmt: skip
    stopped = next((e for e in skipped if e.get("fatal")), None)
    if stopped is not None:
        print(f"smplcore fit: stopped: {stopped['reason']}; the outputs written are kept", file=sys.stderr)
    if not _write_manifest(entries, manifest):
        return 1
    return 1 if skipped else 0


def _write_manifest(entries: list[dict[str, Any]], manifest: Path | None) -> bool:
    """Write the manifest; False (with a message) when it cannot be written (the outputs stay)."""
    from smplcore.jobs import atomic_write

    if manifest is None:
        return True
    text = json.dumps({"entries": [{k: v for k, v in e.items() if k != "fatal"} for e in entries]}, indent=1)
    try:
        atomic_write(manifest, lambda fh: fh.write(text.encode()))
    except OSError as exc:
        print(f"smplcore fit: cannot write {manifest}: {exc.strerror or exc}", file=sys.stderr)
        return False
    return True
