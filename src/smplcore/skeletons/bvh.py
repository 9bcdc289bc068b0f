"""A BVH (Biovision Hierarchy) reader: ``.bvh`` or gzipped ``.bvh.gz`` to a :class:`BVHClip`.

What it accepts, from the files real motion capture comes in (see the shared mocap's README):

* LF, CRLF and a mix of them; tabs or spaces; numbers such as ``.0083333`` or ``-2.47945e-15``;
* any rotation order per joint (``CHANNELS 3 Zrotation Xrotation Yrotation``; one or two rotation channels
  too), position channels on any joint, ``End Site`` blocks, zero-length offsets (``OFFSET 0 0 0``);
* a gzip file (told from its first bytes, not its name), decompressed in chunks up to ``max_bytes``.

Euler angles become rotation matrices with :class:`scipy.spatial.transform.Rotation` (one call per rotation
order over every joint and frame using it), so angles that wrap at ±180° are harmless.

What it refuses, with a :class:`~smplcore.errors.ModelFileError` naming the file and the line: a header that
is not a joint tree (unbalanced braces, a ``CHANNELS`` count that differs from the names listed, unknown
channels), a frame line with more or fewer values than the channels, a value that is not a finite number, a
motion section shorter than its ``Frames:`` (truncated) and a ``Frames:`` that the file is too small to hold
(memory stays proportional to the file: at most ~25 bytes per byte of text).

Frame 0 is a reference pose (a T-pose, not motion) in most cgspeed CMU conversions. It is detected (the root's
rotation exactly zero there but not throughout, every joint within 25° of its rest, a jump of over 5° to frame 1)
and reported as ``clip.reference_pose``; ``drop_reference_pose=True`` drops it. (On the 190 clips of the shared
mocap this finds exactly the 185 that its index marks.)
"""

from __future__ import annotations

import math
import os
import re
import zlib
from pathlib import Path

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.skeletons.clip import BVHClip

__all__ = ["MAX_BVH_BYTES", "parse_bvh", "read_bvh"]

MAX_BVH_BYTES = 1 << 30
"""Largest BVH text read (decompressed): 1 GiB, about four hours of a 43-joint skeleton at 120 fps."""

MAX_JOINTS = 10_000
_CHUNK = 1 << 20
_CHANNELS = {f"{a}{kind}": (a.upper(), kind) for a in "xyzXYZ" for kind in ("position", "rotation")}
_AXIS = {"X": 0, "Y": 1, "Z": 2}


def read_bvh(
    path: str | os.PathLike[str], *, drop_reference_pose: bool = False, max_bytes: int = MAX_BVH_BYTES
) -> BVHClip:
    """Read a ``.bvh`` or ``.bvh.gz`` motion file.

    Parameters
    ----------
    path : the file; gzip is recognised by its first bytes.
    drop_reference_pose : drop frame 0 when it is detected as a reference pose (see the module docstring).
    max_bytes : the largest (decompressed) text read.

    Returns
    -------
    BVHClip in the file's units and axes (``clip.units == "file"``); :func:`smplcore.skeletons.to_metres`
    converts it.

    Raises
    ------
    ModelFileError
        naming the file (and the line): not a regular file, too large, not a BVH, malformed.
    """
    from smplcore.io import open_input

    path = Path(path)
    fh, size = open_input(path, "a BVH motion file (.bvh, .bvh.gz)")
    with fh:
        try:
            head = fh.read(2)
            if head == b"\x1f\x8b":
                data = _gunzip(fh, path, head, max_bytes)
            else:
                if size > max_bytes:
                    raise ModelFileError(path, f"is {size:,} bytes; a BVH file is read only up to {max_bytes:,}")
                data = head + fh.read(size + 1)
        except OSError as exc:
            raise ModelFileError(path, f"cannot read ({exc.strerror or exc})") from None
    return parse_bvh(data.decode("utf-8", errors="replace"), str(path), drop_reference_pose=drop_reference_pose)


def _gunzip(fh, path: Path, head: bytes, max_bytes: int) -> bytes:
    """The decompressed bytes of a gzip stream (members concatenated), refused past ``max_bytes``."""
    out: list[bytes] = []
    total = 0
    pending = head + fh.read(_CHUNK)
    inflate = zlib.decompressobj(wbits=31)
    try:
        while pending:
            piece = inflate.decompress(pending, max(1, max_bytes + 1 - total))
            total += len(piece)
            out.append(piece)
            if total > max_bytes:
                raise ModelFileError(path, f"decompresses to more than {max_bytes:,} bytes; refused")
            if inflate.unconsumed_tail:
                pending = inflate.unconsumed_tail
            elif inflate.eof:
                rest = inflate.unused_data + fh.read(_CHUNK)
                if rest.strip(b"\x00"):  # another gzip member
                    inflate = zlib.decompressobj(wbits=31)
                    pending = rest
                else:
                    pending = b""
            else:
                pending = fh.read(_CHUNK)
                if not pending:
                    raise ModelFileError(path, "the gzip stream is truncated (the file ends inside it)")
    except zlib.error as exc:
        raise ModelFileError(path, f"not a valid gzip file ({exc})") from None
    return b"".join(out)


class _Tokens:
    """The header's tokens with their line numbers (a joint's name is the rest of its line)."""

    def __init__(self, lines: list[str], source: str) -> None:
        self.lines, self.source = lines, source
        self.row, self.pos = 0, 0
        self.items: list[str] = []

    def fail(self, message: str, line: int | None = None) -> ModelFileError:
        return ModelFileError(self.source, f"line {self.line if line is None else line}: {message}")

    @property
    def line(self) -> int:
        return self.row

    def _fill(self) -> bool:
        while self.pos >= len(self.items):
            if self.row >= len(self.lines):
                return False
            self.items, self.pos = self.lines[self.row].split(), 0
            self.row += 1
        return True

    def next(self, what: str) -> str:
        if not self._fill():
            raise self.fail(f"the file ends where {what} was expected (truncated header)")
        token = self.items[self.pos]
        self.pos += 1
        return token

    def peek(self) -> str | None:
        return self.items[self.pos] if self._fill() else None

    def rest_of_line(self, what: str) -> str:
        """The remaining tokens of the current line joined (a joint name may hold spaces), without a ``{``."""
        rest = self.items[self.pos :]
        if rest and rest[-1] == "{":
            rest = rest[:-1]
            self.items, self.pos = ["{"], 0
        else:
            self.pos = len(self.items)
        if not rest:
            raise self.fail(f"{what} has no name")
        return " ".join(rest)

    def number(self, what: str) -> float:
        token = self.next(what)
        try:
            value = float(token)
        except ValueError:
            raise self.fail(f"{what}: expected a number, got {token!r}") from None
        if not math.isfinite(value):
            raise self.fail(f"{what}: {token!r} is not a finite number")
        return value


def _header(tokens: _Tokens):
    """Joints (names, parents, offsets, channels, lines) and End Sites from the ``HIERARCHY`` section."""
    first = tokens.next("HIERARCHY")
    if first.upper() != "HIERARCHY":
        raise tokens.fail(f"expected 'HIERARCHY' (a BVH file starts with it), got {first[:40]!r}")
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    joint_lines: list[int] = []
    ends: list[tuple[int, list[float]]] = []
    stack: list[int] = []  # open blocks: joint index, or -2 for an End Site
    while True:
        word = tokens.next("a joint, '}' or 'MOTION'")
        key = word.upper()
        if key in ("ROOT", "JOINT"):
            if key == "ROOT" and names:
                raise tokens.fail("a second ROOT: files with several skeletons are not supported")
            if key == "JOINT" and not stack:
                raise tokens.fail("a JOINT outside the ROOT's braces")
            if stack and stack[-1] == -2:
                raise tokens.fail("a JOINT inside an End Site")
            line = tokens.line
            name = tokens.rest_of_line(key)
            if name in names:
                raise tokens.fail(f"the joint name {name!r} is used twice")
            if len(names) >= MAX_JOINTS:
                raise tokens.fail(f"more than {MAX_JOINTS} joints")
            if tokens.next("'{'") != "{":
                raise tokens.fail(f"expected '{{' after {key} {name}")
            parents.append(stack[-1] if stack else -1)
            names.append(name)
            joint_lines.append(line)
            offsets.append(_offset(tokens, name))
            channels.append(_channels(tokens, name))
            stack.append(len(names) - 1)
        elif key == "END":
            if not stack or stack[-1] == -2:
                raise tokens.fail("an End Site outside a joint")
            if tokens.next("'Site'").upper() != "SITE" or tokens.next("'{'") != "{":
                raise tokens.fail("expected 'End Site {'")
            ends.append((stack[-1], _offset(tokens, "End Site")))
            stack.append(-2)
        elif word == "}":
            if not stack:
                raise tokens.fail("'}' without an open joint")
            stack.pop()
        elif key == "MOTION":
            if stack:
                raise tokens.fail(f"'MOTION' with {len(stack)} joint block(s) still open (missing '}}')")
            if not names:
                raise tokens.fail("'MOTION' before any ROOT joint")
            return names, parents, offsets, channels, joint_lines, ends
        else:
            raise tokens.fail(f"expected JOINT, End Site, '}}' or MOTION, got {word[:40]!r}")


def _offset(tokens: _Tokens, name: str) -> list[float]:
    word = tokens.next(f"OFFSET of {name}")
    if word.upper() != "OFFSET":
        raise tokens.fail(f"{name}: expected 'OFFSET x y z', got {word[:40]!r}")
    return [tokens.number(f"{name}: OFFSET") for _ in range(3)]


def _channels(tokens: _Tokens, name: str) -> tuple[str, ...]:
    if (tokens.peek() or "").upper() != "CHANNELS":
        return ()  # a joint without channels
    tokens.next("CHANNELS")
    line = tokens.line
    count_text = tokens.next(f"{name}: the channel count")
    if not count_text.isdigit() or int(count_text) > 6:
        raise tokens.fail(f"{name}: CHANNELS: expected a count from 0 to 6, got {count_text!r}")
    count = int(count_text)
    out: list[str] = []
    for _ in range(count):
        word = tokens.peek()
        if word is None or word not in _CHANNELS and word.lower() not in {c.lower() for c in _CHANNELS}:
            listed = f"{len(out)} channel name(s) ({' '.join(out) or 'none'})"
            expected = "expected Xposition ... Zrotation"
            raise tokens.fail(f"{name}: CHANNELS {count} lists {listed} then {word!r}: {expected}", line)
        tokens.next("a channel")
        out.append(word[0].upper() + word[1:].lower())
    if len(set(out)) != len(out):
        raise tokens.fail(f"{name}: a channel is listed twice in {' '.join(out)}", line)
    nxt = tokens.peek()
    if nxt is not None and nxt.lower() in {c.lower() for c in _CHANNELS}:
        raise tokens.fail(f"{name}: CHANNELS {count} but more channel names follow ({nxt})", line)
    return tuple(out)


_FRAMES = re.compile(r"^\s*frames\s*:?\s*(\S+)\s*$", re.IGNORECASE)
_FRAME_TIME = re.compile(r"^\s*frame\s*time\s*:?\s*(\S+)\s*$", re.IGNORECASE)


def parse_bvh(text: str, source: str = "<string>", *, drop_reference_pose: bool = False) -> BVHClip:
    """A :class:`BVHClip` from BVH text (``source`` names it in messages); see :func:`read_bvh`."""
    lines = text.splitlines()
    tokens = _Tokens(lines, source)
    names, parents, offsets, channels, joint_lines, ends = _header(tokens)
    if tokens.pos < len(tokens.items):
        raise tokens.fail(f"unexpected {' '.join(tokens.items[tokens.pos :])[:40]!r} after MOTION")
    row = tokens.row
    values, frame_time, first_line = _motion(lines, row, source, channels, names)
    return _build(names, parents, offsets, channels, ends, values, frame_time, source, first_line,
                  drop_reference_pose)  # fmt: skip


def _next_nonblank(lines: list[str], row: int) -> int:
    while row < len(lines) and not lines[row].strip():
        row += 1
    return row


def _motion(lines, row, source, channels, names):
    """(T, C) channel values, the frame time and the line number of the first frame."""
    width = sum(len(c) for c in channels)
    row = _next_nonblank(lines, row)
    match = _FRAMES.match(lines[row]) if row < len(lines) else None
    if match is None:
        raise ModelFileError(source, f"line {row + 1}: expected 'Frames: N' after MOTION")
    try:
        frames = int(match.group(1))
    except ValueError:
        raise ModelFileError(
            source, f"line {row + 1}: Frames: expected a whole number, got {match.group(1)!r}"
        ) from None
    if frames < 1:
        raise ModelFileError(source, f"line {row + 1}: Frames: {frames}: the file holds no motion")
    row = _next_nonblank(lines, row + 1)
    match = _FRAME_TIME.match(lines[row]) if row < len(lines) else None
    if match is None:
        raise ModelFileError(source, f"line {row + 1}: expected 'Frame Time: seconds' after Frames")
    try:
        frame_time = float(match.group(1))
    except ValueError:
        frame_time = math.nan
    if not (math.isfinite(frame_time) and 0 < frame_time < 3600):
        raise ModelFileError(
            source, f"line {row + 1}: Frame Time: expected seconds per frame > 0, got {match.group(1)!r}"
        )
    start = row + 1
    if width == 0:
        raise ModelFileError(source, f"line {start}: no joint has CHANNELS: the file holds no motion")
    # a frame of ``width`` values needs at least 2 x width bytes ("0 "): a Frames: the text cannot hold is refused
    # before anything is allocated for it
    available = sum(len(s) + 1 for s in lines[start:])
    if frames * width * 2 - 1 > available:
        raise ModelFileError(
            source,
            f"line {row}: Frames: {frames} frames of {width} values need at least {frames * width * 2 - 1:,} bytes, "
            f"the motion section has {available:,}: the file is truncated or Frames is wrong",
        )
    data = [(k, s) for k, s in enumerate(lines[start:], start + 1) if s.strip()]
    if len(data) < frames:
        last = data[-1][0] if data else start
        raise ModelFileError(
            source, f"line {last}: truncated motion: Frames: {frames} but the file ends after {len(data)} frame line(s)"
        )
    data = data[:frames]  # lines after the declared frames are ignored (as other readers do)
    split = [s.split() for _, s in data]
    for (number, _), items in zip(data, split):
        if len(items) != width:
            raise ModelFileError(
                source, f"line {number}: {len(items)} values in a frame line, the CHANNELS declare {width}"
            )
    flat = [v for items in split for v in items]
    try:
        values = np.array(flat, dtype=np.float64).reshape(frames, width)
    except ValueError:
        for (number, _), items in zip(data, split):
            for c, v in enumerate(items):
                try:
                    float(v)
                except ValueError:
                    raise ModelFileError(source, f"line {number}: value {c + 1} ({_channel_name(channels, names, c)}) "
                                         f"is {v[:40]!r}, not a number") from None  # fmt: skip
        raise
    bad = np.argwhere(~np.isfinite(values))
    if len(bad):
        t, c = bad[0]
        raise ModelFileError(
            source,
            f"line {data[t][0]}: value {c + 1} ({_channel_name(channels, names, c)}) is {split[t][c]!r}, not a "
            f"finite number" + (f" ({len(bad)} such values)" if len(bad) > 1 else ""),
        )
    return values, frame_time, start


def _channel_name(channels, names, column: int) -> str:
    for name, chans in zip(names, channels):
        if column < len(chans):
            return f"{name} {chans[column]}"
        column -= len(chans)
    return "?"


def _build(names, parents, offsets, channels, ends, values, frame_time, source, first_line, drop) -> BVHClip:
    from scipy.spatial.transform import Rotation

    frames, count = len(values), len(names)
    offsets_a = np.asarray(offsets, np.float64).reshape(count, 3)
    translations = np.broadcast_to(offsets_a, (frames, count, 3)).copy()
    rotations = np.broadcast_to(np.eye(3), (frames, count, 3, 3)).copy()
    by_order: dict[str, list[tuple[int, list[int]]]] = {}
    column = 0
    for j, chans in enumerate(channels):
        order, cols = "", []
        for c, name in enumerate(chans):
            axis, kind = _CHANNELS[name]
            if kind == "position":
                translations[:, j, _AXIS[axis]] = values[:, column + c]
            else:
                order += axis
                cols.append(column + c)
        if order:
            by_order.setdefault(order, []).append((j, cols))
        column += len(chans)
    for order, joints in by_order.items():  # one scipy call per rotation order: every joint and frame at once
        ids = [j for j, _ in joints]
        angles = values[:, [c for _, cols in joints for c in cols]].reshape(frames, len(ids), len(order))
        matrices = Rotation.from_euler(order, angles.reshape(-1, len(order)), degrees=True).as_matrix()
        rotations[:, ids] = matrices.reshape(frames, len(ids), 3, 3)
    reference = _is_reference_pose(values, channels)
    clip = BVHClip(
        joint_names=tuple(names),
        parents=np.asarray(parents, np.int64),
        offsets=offsets_a,
        channels=tuple(channels),
        rotations=rotations,
        translations=translations,
        frame_time=float(frame_time),
        end_parents=np.asarray([p for p, _ in ends], np.int64),
        end_offsets=np.asarray([o for _, o in ends], np.float64).reshape(len(ends), 3),
        source=source,
        reference_pose=reference,
    )
    return clip.without_reference_pose() if drop else clip


def _is_reference_pose(values: np.ndarray, channels) -> bool:
    """Frame 0 is a reference pose: the root's rotation channels exactly zero in frame 0 but not in all frames (real
    motion never holds exact zeros), every rotation channel of frame 0 within 25 degrees (a rest or T-pose), and a
    jump of more than 5 degrees to frame 1."""
    if len(values) < 2:
        return False
    rot = [c for c, name in enumerate(n for chans in channels for n in chans) if name.endswith("rotation")]
    root = [c for c, name in enumerate(channels[0]) if name.endswith("rotation")]
    if not rot or not root or np.any(values[0, root] != 0.0) or np.all(values[:, root] == 0.0):
        return False
    step = np.abs((values[1, rot] - values[0, rot] + 180.0) % 360.0 - 180.0).max()
    return bool(np.abs(values[0, rot]).max() <= 25.0 and step > 5.0)
