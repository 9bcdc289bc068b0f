"""Checks before a run starts: a script that worker processes would re-run, and how much will be written."""

from __future__ import annotations

import ast
import multiprocessing
import os
import sys
import zipfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.motion.process.options import ProcessError, ProcessOptions
from smplcore.motion.process.task import Task
from smplcore.motion.sequence import FPS_KEYS

GUARD_HELP = (
    'put the call under `if __name__ == "__main__":` (as in docs/motion.md), or pass workers=0 to run in this process'
)


class OutputSizeWarning(UserWarning):
    """The run is about to write more than ``warn_bytes`` (see :func:`smplcore.motion.process_tree`)."""


def check_not_reimported() -> None:
    """Refuse to run inside a worker process that is re-importing its parent's main script.

    Raises
    ------
    ProcessError
        when this call comes from the top level of a main script being imported by a spawned or
        forkserver worker (the script lacks ``if __name__ == "__main__":``).
    """
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise ProcessError(
            "process_tree was called while this worker process was importing its parent's main script: the "
            f"script calls it at its top level, so every worker would run it again; {GUARD_HELP}"
        )


def check_main_guard() -> None:
    """Refuse a pool run started from the top level of the main script outside ``if __name__ == "__main__":``.

    Worker processes (spawn, forkserver) import the main script before they run anything; an unguarded
    call would start the run again in every worker. Calls from an interactive session, ``python -c``
    or code under the guard are fine.

    Raises
    ------
    ProcessError
        naming the script and the line, and saying how to fix it.
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or not path:
        return
    if getattr(getattr(main, "__spec__", None), "name", None) is None and not os.path.isfile(path):
        raise ProcessError(
            f"the main script {path!r} is not a file: worker processes import the main script before they "
            "start, and cannot import this one; save the code as a .py file and run that, or pass workers=0"
        )
    frame: Any = sys._getframe(1)
    line = None
    while frame is not None:
        if frame.f_globals is main.__dict__ and frame.f_code.co_name == "<module>":
            line = frame.f_lineno
        frame = frame.f_back
    if line is None:  # not called while the script's top level runs (e.g. from a function called later)
        return
    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError):
        return
    if not _guarded(tree.body, line):
        raise ProcessError(
            f"{path}, line {line}: process_tree with worker processes is called at the top level of the script, "
            f"which each worker imports again (it would run the job again in every worker); {GUARD_HELP}"
        )


def _is_main_guard(node: ast.stmt) -> bool:
    if not isinstance(node, ast.If) or not isinstance(node.test, ast.Compare):
        return False
    sides = [node.test.left, *node.test.comparators]
    names = [s for s in sides if isinstance(s, ast.Name) and s.id == "__name__"]
    consts = [s for s in sides if isinstance(s, ast.Constant) and s.value == "__main__"]
    return len(sides) == 2 and bool(names) and bool(consts) and isinstance(node.test.ops[0], ast.Eq)


def _guarded(body: list[ast.stmt], line: int) -> bool:
    """Whether ``line`` lies inside an ``if __name__ == "__main__":`` block among ``body``'s statements."""
    for node in body:
        if not node.lineno <= line <= (node.end_lineno or node.lineno):
            continue
        if _is_main_guard(node):
            return any(n.lineno <= line <= (n.end_lineno or n.lineno) for n in node.body)  # type: ignore[attr-defined]
        for name in ("body", "orelse", "finalbody"):
            if _guarded(getattr(node, name, None) or [], line):
                return True
        for handler in getattr(node, "handlers", None) or []:
            if _guarded(handler.body, line):
                return True
        return False
    return False


# --------------------------------------------------------------------------------------------------
# Output size


def _npy_header_shape(fh: Any) -> tuple[int, ...]:
    version = np.lib.format.read_magic(fh)
    read = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    return tuple(read[version](fh)[0])


def input_frames(path: str | Path) -> tuple[int, int, float | None] | None:
    """(frames, pose values per frame, frame rate or None) of an AMASS-style ``.npz``, from its headers only
    (None when it cannot tell: such a file is counted as empty)."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = set(archive.namelist())
            if "poses.npy" not in names:
                return None
            with archive.open("poses.npy") as fh:
                shape = _npy_header_shape(fh)
            fps = None
            for key in FPS_KEYS:
                if f"{key}.npy" in names and archive.getinfo(f"{key}.npy").file_size < 4096:
                    with archive.open(f"{key}.npy") as fh:
                        fps = float(np.lib.format.read_array(fh, allow_pickle=False).reshape(-1)[0])
                    break
    except Exception:  # noqa: BLE001 -- a damaged file is reported when it is processed
        return None
    if len(shape) != 2:
        return None
    return int(shape[0]), int(shape[1]), fps


def estimate_output_bytes(tasks: Iterable[Task], options: ProcessOptions) -> int:
    """About how many bytes the outputs of ``tasks`` take (uncompressed: an upper bound with ``compress``)."""
    from smplcore.family.specs import get_spec
    from smplcore.motion.sequence import POSE_WIDTH

    by_width = {v: k for k, v in POSE_WIDTH.items()}
    itemsize = np.dtype(options.dtype).itemsize
    total = 0
    for task in tasks:
        found = input_frames(task.source)
        if found is None:
            continue
        frames, width, fps = found
        if options.fps is not None and fps and fps > 0:
            if options.resample == "stride":
                frames = -(-frames // max(1, int(fps / options.fps)))
            else:
                frames = int(round(frames * options.fps / fps))
        model_type = options.model_type or (by_width.get(width, "smplh") if options.model_path else "open")
        try:
            spec = get_spec(model_type)
        except (KeyError, ValueError):
            continue
        joints = len(spec.joint_names) + (30 if options.extra_joints else 0)
        if options.num_joints is not None:
            joints = min(joints, options.num_joints)
        per_frame = joints * 3 * itemsize + (8 if options.format == "npz" else 0)
        if options.vertices:
            per_frame += (spec.num_vertices or _open_vertices()) * 3 * itemsize
        total += frames * per_frame
    return total


def _open_vertices() -> int:
    """The packaged open model's vertex count (from its header)."""
    from smplcore.io import OPEN_MODEL_PATH

    try:
        with zipfile.ZipFile(OPEN_MODEL_PATH) as archive, archive.open("v_template.npy") as fh:
            return int(_npy_header_shape(fh)[0])
    except Exception:  # noqa: BLE001 -- an estimate: SMPL's count will do
        return 6890


def _size(n: float) -> str:
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.1f} MB"


def size_message(estimate: int, output_dir: Path, files: int, free: int | None) -> str:
    text = f"about {_size(estimate)} will be written to {output_dir} ({files} files)"
    if free is not None:
        text += f"; the disk has {_size(free)} free"
        if free < estimate:
            text += " (not enough: the run will stop when the disk is full; a rerun after freeing space resumes)"
    return text
