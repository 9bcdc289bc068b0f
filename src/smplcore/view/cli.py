"""``smplcore view`` (a browser viewer) and ``smplcore render`` (a motion to MP4 / GIF). Registered by
:mod:`smplcore.cli`.

Examples::

    smplcore view                                   # the open model, in the browser at http://127.0.0.1:8080/
    smplcore view walk.npz run.bvh --port 8090      # two motions side by side on a timeline
    smplcore view fit.npz --keypoints target.npy --model-path models/ --model-type smplx
    smplcore render walk.npz -o walk.mp4 --size 640x480 --camera follow
    smplcore render walk.npz -o walk.gif --fps 15 --size 320x240 --fit-over target.npy
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path

from smplcore.view._deps import MissingDependencyError


def _size(text: str) -> tuple[int, int]:
    parts = text.lower().replace("*", "x").split("x")
    try:
        values = [int(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}") from None
    if len(values) == 1:
        values = values * 2
    if len(values) != 2:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}")
    return values[0], values[1]


def _model_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model-path", default=None, help="model file or folder (default: the open model)")
    parser.add_argument("--model-type", default=None, help="smpl, smplh, smplx, mano, flame or open")
    parser.add_argument("--gender", default=None, help="model gender (default: the motion's, else neutral)")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``smplcore view`` and ``smplcore render``."""
    view = subparsers.add_parser(
        "view",
        help="look at bodies and motions in the browser (needs smplcore[view])",
        description="Serve a browser viewer: one body per MODEL_OR_MOTION (a model file, an AMASS-style "
        ".npz, a parameter set .npz/.json, a .bvh written by `smplcore export`), side by side; the open "
        "model when none is given. Sliders for shape and expression, a joint picker with rotations, a "
        "timeline for motions, skeleton and joint names, save buttons. Ctrl-C stops it.",
    )
    view.add_argument("inputs", nargs="*", type=Path, metavar="MODEL_OR_MOTION")
    view.add_argument("--port", type=int, default=8080, help="HTTP port (default: %(default)s, or the next free one)")
    view.add_argument("--host", default="127.0.0.1", help="address to listen on (default: %(default)s)")
    _model_options(view)
    view.add_argument("--keypoints", type=Path, default=None, help="target keypoints (.npy/.npz) over the first body")
    view.add_argument("--out-dir", type=Path, default=Path("."), help="where the save buttons write (default: .)")
    view.add_argument(
        "--lighting",
        choices=("studio", "simple"),
        default="studio",
        help="studio: environment map and shadows (default); simple: faster where WebGL runs in software",
    )
    view.set_defaults(run=run_view)

    render = subparsers.add_parser(
        "render",
        help="render a motion to an MP4 or GIF video (needs smplcore[view,render])",
        description="Render MOTION (an AMASS-style .npz, a parameter set with one row per frame, a .bvh) "
        "with the offscreen renderer and write it through ffmpeg (imageio-ffmpeg): H.264 .mp4 or .gif.",
    )
    render.add_argument("input", type=Path, metavar="MOTION")
    render.add_argument("-o", "--output", type=Path, required=True, metavar="OUT", help="output .mp4 or .gif")
    render.add_argument("--fps", type=float, default=None, help="video frame rate (default: the motion's)")
    render.add_argument("--size", type=_size, default=(640, 480), help="WIDTHxHEIGHT in pixels (default: 640x480)")
    render.add_argument("--camera", choices=("follow", "fixed"), default="follow", help="default: %(default)s")
    render.add_argument(
        "--view", choices=("front", "three_quarter", "side"), default="front", help="camera side (default: front)"
    )
    render.add_argument("--fit-over", type=Path, default=None, metavar="KEYPOINTS", help="target keypoints to draw")
    render.add_argument("--batch", type=int, default=32, help="frames posed per model call (default: %(default)s)")
    _model_options(render)
    render.add_argument("--no-progress", "--quiet", dest="no_progress", action="store_true", help="no progress bar")
    render.set_defaults(run=run_render)


def _missing(command: str, exc: MissingDependencyError) -> int:
    print(f"smplcore {command}: {exc}", file=sys.stderr)
    return 2


def _one_line_warnings(command: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """A command whose warnings about the inputs (another shape space, coefficients dropped: UserWarnings) are
    printed as one line ``smplcore COMMAND: warning: ...``, not as Python's two pointing into smplcore."""

    def decorate(run: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(run)
        def wrapper(args: argparse.Namespace) -> int:
            with warnings.catch_warnings():
                show = warnings.showwarning

                def showwarning(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001, ANN202
                    if issubclass(category, UserWarning):
                        print(f"smplcore {command}: warning: {message}", file=sys.stderr, flush=True)
                    else:
                        show(message, category, filename, lineno, file, line)

                warnings.showwarning = showwarning
                return run(args)

        return wrapper

    return decorate


def _bodies(count: int) -> str:
    return f"{count} body" if count == 1 else f"{count} bodies"


@_one_line_warnings("view")
def run_view(args: argparse.Namespace) -> int:
    from smplcore.view.viewer import Viewer

    try:
        viewer = Viewer(
            list(args.inputs),
            model_path=args.model_path,
            model_type=args.model_type,
            gender=args.gender,
            port=args.port,
            host=args.host,
            keypoints=args.keypoints,
            out_dir=args.out_dir,
            lighting=args.lighting,
        )
    except MissingDependencyError as exc:
        return _missing("view", exc)
    url = viewer.url if args.host in ("127.0.0.1", "localhost") else viewer.url.replace("127.0.0.1", args.host)
    print(f"smplcore view: serving {_bodies(len(viewer.bodies))} at {url}", flush=True)
    print("  (open this address: it holds this session's token; other pages and web origins are refused)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        viewer.close()
    return 0


class _Bar:
    """A tqdm bar made once the number of frames is known (no bar without tqdm, the cli extra)."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.bar = None

    def start(self, total: int) -> None:
        try:
            from tqdm import tqdm
        except ImportError:
            return
        self.bar = tqdm(total=total, unit="frame", desc="render", file=sys.stderr, leave=False)

    def update(self, count: int) -> None:
        if self.bar is not None:
            self.bar.update(count)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


@_one_line_warnings("render")
def run_render(args: argparse.Namespace) -> int:
    from smplcore.view.video import render_video

    bar = _Bar(not args.no_progress)
    width, height = args.size
    try:
        report = render_video(
            args.input,
            args.output,
            model_path=args.model_path,
            model_type=args.model_type,
            gender=args.gender,
            fps=args.fps,
            width=width,
            height=height,
            camera=args.camera,
            view=args.view,
            keypoints=args.fit_over,
            batch=args.batch,
            progress=bar.update if bar.enabled else None,
            on_start=bar.start if bar.enabled else None,
        )
    except MissingDependencyError as exc:
        return _missing("render", exc)
    except RuntimeError as exc:  # no offscreen OpenGL context: the message says how to fix it
        print(f"smplcore render: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the video could not be written whole (VideoWriteError), or its folder made
        print(f"smplcore render: error: {exc.strerror if isinstance(exc.strerror, str) else exc}", file=sys.stderr)
        return 1
    finally:
        bar.close()
    print(report.summary())
    return 0
