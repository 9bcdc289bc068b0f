"""``smplcore render`` on a full disk: what ffmpeg wrote is decoded back; a video short of frames (a GIF cut off,
an MP4 without its index) is an error with exit status 1, and nothing is left at the output path. The disk is a
real 64 KiB tmpfs (mounted as root; skipped where mounting is not allowed)."""

from __future__ import annotations

import contextlib
import subprocess
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("imageio_ffmpeg", reason="video needs imageio-ffmpeg: pip install 'smplcore[view]'")

from smplcore.cli import main  # noqa: E402
from smplcore.motion import save_motion  # noqa: E402
from smplcore.view.video import VideoWriteError, decoded_frames, render_video  # noqa: E402
from test_view_video import gl, walk  # noqa: E402, F401 - the fixture skips without offscreen OpenGL

pytestmark = pytest.mark.usefixtures("gl")


@contextlib.contextmanager
def small_disk(path: Path, size: str = "64k"):
    path.mkdir()
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True)
    if result.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here ({result.stderr.decode().strip()})")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


def _fill(disk: Path, leave: int) -> None:
    """Fill ``disk`` until at most ``leave`` bytes are free."""
    import shutil

    with open(disk / "filler", "wb") as fh:
        with contextlib.suppress(OSError):
            while shutil.disk_usage(disk).free > leave:
                fh.write(bytes(min(4096, max(1, shutil.disk_usage(disk).free - leave))))
                fh.flush()


@pytest.mark.parametrize("suffix, leave", [(".gif", 24 << 10), (".mp4", 6 << 10)])
def test_a_video_cut_short_by_a_full_disk_is_an_error_and_is_not_left(tmp_path, suffix, leave):
    motion = walk(12)
    with small_disk(tmp_path / "disk") as disk:
        _fill(disk, leave)
        out = disk / f"walk{suffix}"
        with pytest.raises(VideoWriteError, match=r"could not be written whole.* of 12 frames decode back"):
            render_video(motion, out, width=160, height=120, camera="fixed")
        assert sorted(p.name for p in disk.iterdir()) == ["filler"]  # no output, no partial file
        # the command: exit status 1 and the message, not "wrote ... (12 frames)"
        source = save_motion(motion, tmp_path / "walk.npz")
        assert main(["render", str(source), "-o", str(out), "--size", "160x120", "--no-progress"]) == 1
        assert sorted(p.name for p in disk.iterdir()) == ["filler"]


def test_the_written_video_is_verified_and_renamed_into_place(tmp_path, capsys):
    motion = walk(6)
    out = tmp_path / "ok.gif"
    report = render_video(motion, out, width=64, height=48, camera="fixed")
    assert report.frames == 6 and decoded_frames(out) == 6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.gif"]
    truncated = tmp_path / "cut.gif"
    truncated.write_bytes(out.read_bytes()[: out.stat().st_size // 2])
    assert 0 < decoded_frames(truncated) < 6
    (tmp_path / "broken.mp4").write_bytes(b"\0\0\0\x20ftypisom" + bytes(100))
    assert decoded_frames(tmp_path / "broken.mp4") == 0


def test_a_read_only_or_missing_output_folder_is_a_message(tmp_path, capsys):
    source = save_motion(walk(4), tmp_path / "walk.npz")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["render", str(source), "-o", str(blocker / "sub" / "v.gif"), "--size", "64x48"]) == 1
    assert "cannot make the folder" in capsys.readouterr().err
    assert np.all(blocker.read_text() == "x")
