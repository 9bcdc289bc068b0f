"""Looking at bodies: a browser viewer (``viser``) and video rendering (needs the ``view`` extra:
``pip install "smplcore[view]"``; the video writer also needs the ``render`` extra).

* :func:`show` / :class:`Viewer`: bodies in the browser with shape, expression and joint controls, a motion
  timeline, skeleton and joint names, model / gender switch and save buttons (``smplcore view``).
* :func:`render_video`: a motion to MP4 or GIF with the offscreen renderer (``smplcore render``).
"""

from smplcore.view._deps import MissingDependencyError
from smplcore.view.bodies import Body, build_model
from smplcore.view.show import show
from smplcore.view.sources import BvhMotion, Source, load_keypoints, load_source, read_bvh
from smplcore.view.video import render_video
from smplcore.view.viewer import Viewer

__all__ = [
    "Body",
    "BvhMotion",
    "MissingDependencyError",
    "Source",
    "Viewer",
    "build_model",
    "load_keypoints",
    "load_source",
    "read_bvh",
    "render_video",
    "show",
]
