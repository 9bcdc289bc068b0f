#!/usr/bin/env python
"""docs/fbx_blender.png: the open model walking a step, written as FBX by smplcore with the UV-grid texture
embedded, imported by Blender's own FBX importer (headless) and rendered with its Workbench engine (texture
colours) at the last frame.

    python tools/render_fbx_blender.py [OUT.png]     # needs the `blender` program (apt-get install blender)
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import smplcore
from smplcore.export import save_fbx

ROOT = Path(__file__).resolve().parents[1]


def step(frames: int = 30) -> dict[str, np.ndarray]:
    """A short pose change from the rest pose: arms down, one leg forward, the other knee bent, head turned."""
    pose = np.zeros((23, 3))  # body_pose rows are joints 1..23
    pose[15] = (0.0, 0.0, -1.15)  # left_shoulder
    pose[16] = (0.0, 0.0, 1.15)  # right_shoulder
    pose[17] = (0.0, -0.5, 0.0)  # left_elbow
    pose[18] = (0.0, 0.7, 0.0)  # right_elbow
    pose[0] = (-0.45, 0.0, 0.05)  # left_hip forward
    pose[1] = (0.3, 0.0, -0.05)  # right_hip back
    pose[4] = (0.55, 0.0, 0.0)  # right_knee
    pose[14] = (0.0, 0.35, 0.0)  # head
    t = np.linspace(0.0, 1.0, frames)[:, None]
    return {"body_pose": t * pose.reshape(1, -1), "transl": np.c_[np.zeros(frames), np.zeros(frames), 0.3 * t[:, 0]]}


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "fbx_blender.png"
    blender = shutil.which("blender")
    if blender is None:
        raise SystemExit("needs the blender program (apt-get install blender)")
    model = smplcore.BodyModel(model_type="open")
    with tempfile.TemporaryDirectory() as tmp:
        fbx = Path(tmp) / "step.fbx"
        print(save_fbx(fbx, model, step(), up_axis="z", texture="uv-grid").summary())
        script = ROOT / "tests" / "fbx_blender_check.py"
        command = [blender, "-b", "--factory-startup", "--python-exit-code", "1", "-P", str(script)]
        subprocess.run(command + ["--", str(fbx), "29", "--png", str(out)], check=True, capture_output=True)
    print(f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
