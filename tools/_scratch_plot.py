"""SCRATCH: front/side renders of retargeted frames (mesh, mocap targets as red spheres)."""
import numpy as np
from PIL import Image, ImageDraw
from smplcore.engine import rodrigues
from smplcore.render import render_mesh


def plot(model, params, pts, frames, out, title=""):
    o = model(**params)
    J, V = np.asarray(o.joints), np.asarray(o.vertices)
    tiles = []
    for t in frames:
        R = rodrigues(np.asarray(params["global_orient"], np.float64)[t : t + 1])[0]
        fwd = R[:, 2]
        yaw = np.arctan2(fwd[0], fwd[2])
        c, s = np.cos(yaw), np.sin(yaw)
        Y = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # undo the pelvis heading
        ctr = J[t, 0]
        vv, pp = (V[t] - ctr) @ Y.T, (pts[t] - ctr) @ Y.T
        row = [render_mesh(vv, model.rig.faces, width=300, height=360, camera=cam, joints=pp, alpha=0.6,
                           joint_radius=0.02) for cam in ("front", "side")]
        tiles.append(np.concatenate(row, axis=1))
    img = Image.fromarray(np.concatenate(tiles, axis=0))
    d = ImageDraw.Draw(img)
    for i, t in enumerate(frames):
        d.text((5, 5 + 360 * i), f"{title} t={t}: front | side (from the left)", fill="black")
    img.save(out)
