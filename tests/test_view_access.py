"""The viewer lets in only clients with this session's token and a local web origin; values a client sends
are checked (NaN and inf refused, out-of-range clamped) and bursts of slider moves are merged.

A raw websocket client speaks viser's protocol here (msgpack messages, as viser's browser client sends them)
so that the ``Origin`` header can be forged, as a page of another site would send it."""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest

viser = pytest.importorskip("viser", reason="the viewer needs viser: pip install 'smplcore[view]'")
websockets_sync = pytest.importorskip("websockets.sync.client")  # viser's dependencies, as msgspec
msgspec = pytest.importorskip("msgspec")

from viser import _messages  # noqa: E402

from smplcore.view import Viewer  # noqa: E402
from smplcore.view.access import SessionGate  # noqa: E402


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture()
def viewer(tmp_path):
    with Viewer(port=free_port(), out_dir=tmp_path, lighting="simple") as v:
        yield v


def _connect(viewer, origin: str | None, token: str | None):
    path = "/" if token is None else f"/{token}"
    return websockets_sync.connect(
        f"ws://127.0.0.1:{viewer.port}{path}",
        origin=origin,
        subprotocols=[f"viser-v{viser.__version__}"],
        max_size=None,
        open_timeout=30,
    )


def _send(ws, message) -> None:
    ws.send(msgspec.msgpack.encode(message.as_serializable_dict()))


def _camera() -> _messages.ViewerCameraMessage:
    return _messages.ViewerCameraMessage(
        wxyz=(1.0, 0.0, 0.0, 0.0), position=(0.0, 1.0, 3.0), fov=1.0, near=0.01, far=100.0,
        image_height=480, image_width=640, look_at=(0.0, 1.0, 0.0), up_direction=(0.0, 1.0, 0.0),
    )  # fmt: skip


def _received(ws, seconds: float = 3.0) -> tuple[list[bytes], int | None]:
    """Messages received within ``seconds`` and the close code (None: still open)."""
    from websockets.exceptions import ConnectionClosed

    messages, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            messages.append(ws.recv(timeout=max(0.01, end - time.monotonic())))
        except TimeoutError:
            break
        except ConnectionClosed as exc:
            return messages, exc.rcvd.code if exc.rcvd is not None else 1006
    return messages, None


def _wait(condition, seconds: float = 30.0) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


def _move(ws, slider, value) -> None:
    _send(ws, _messages.GuiUpdateMessage(uuid=slider._impl.uuid, updates={"value": value}))


@pytest.mark.parametrize(
    "origin, with_token",
    [("http://evil.example", False), ("http://evil.example", True), ("http://127.0.0.1:{port}", False)],
)
def test_a_foreign_origin_or_a_missing_token_is_refused(viewer, tmp_path, origin, with_token):
    origin = origin.format(port=viewer.port)
    betas = viewer.bodies[0].betas.copy()
    with _connect(viewer, origin, viewer.gate.token if with_token else None) as ws:
        with pytest.raises(Exception):  # noqa: B017,PT011 - closed (or closing) under it: any send may fail
            _send(ws, _camera())
            _move(ws, viewer.controls.betas[0], 2.5)  # a slider move
            _send(ws, _messages.GuiUpdateMessage(uuid=viewer.controls.save_mesh._impl.uuid, updates={"value": True}))
            time.sleep(1.0)
            _send(ws, _camera())
        messages, code = _received(ws)
    assert code == 1008  # policy violation
    assert messages == []  # no mesh, nothing at all
    time.sleep(0.5)
    np.testing.assert_array_equal(viewer.bodies[0].betas, betas)  # no slider moved
    assert list(tmp_path.iterdir()) == []  # nothing saved
    assert viewer.gate.refused and viewer.gate.refused[-1][0] == origin


def test_the_session_token_and_a_local_origin_get_the_scene_and_move_sliders(viewer):
    with _connect(viewer, f"http://127.0.0.1:{viewer.port}", viewer.gate.token) as ws:
        _send(ws, _camera())
        messages, code = _received(ws, 2.0)
        assert code is None and len(messages) > 0
        assert sum(len(m) for m in messages) > 100_000  # the scene came: the mesh's vertices and faces
        _move(ws, viewer.controls.betas[0], 1.5)
        assert _wait(lambda: viewer.bodies[0].betas[0] == 1.5)
    assert viewer.url.startswith(f"http://127.0.0.1:{viewer.port}/?websocket=ws%3A%2F%2F127.0.0.1%3A")
    assert viewer.url.endswith(viewer.gate.token)


def test_nan_and_inf_from_a_client_are_refused_and_updates_go_on(viewer):
    slider = viewer.controls.betas[0]
    with _connect(viewer, None, viewer.gate.token) as ws:  # a script: no Origin
        _send(ws, _camera())
        _received(ws, 1.0)
        _move(ws, slider, 1.0)
        assert _wait(lambda: viewer.bodies[0].betas[0] == 1.0)
        refreshes = len(viewer.timings)
        _move(ws, slider, float("nan"))
        _move(ws, viewer.controls.rotation[0], float("inf"))
        _move(ws, slider, 1e300)  # out of range: clamped to +3
        assert _wait(lambda: viewer.bodies[0].betas[0] == 3.0)
        assert np.all(np.isfinite(viewer.bodies[0].betas)) and np.all(np.isfinite(viewer.bodies[0].full_pose))
        _move(ws, slider, -0.5)  # updates still work for everyone
        assert _wait(lambda: viewer.bodies[0].betas[0] == -0.5 and slider.value == -0.5), (
            viewer.bodies[0].betas[0],
            slider.value,
        )
        assert _wait(lambda: len(viewer.timings) > refreshes)
        verts, _ = viewer.bodies[0].evaluate()
        assert np.all(np.isfinite(verts))


def test_a_burst_of_slider_moves_is_merged_latest_wins(viewer):
    slider = viewer.controls.betas[1]
    with _connect(viewer, None, viewer.gate.token) as ws:
        _send(ws, _camera())
        _received(ws, 1.0)
        before = len(viewer.timings)
        with viewer._lock:  # a refresh that takes long: the moves arrive meanwhile
            values = np.linspace(-2.0, 2.0, 200)
            for value in values:
                _move(ws, slider, float(value))
            assert _wait(lambda: slider.value == 2.0)
        assert _wait(lambda: viewer.bodies[0].betas[1] == 2.0 and len(viewer.timings) > before)
        time.sleep(0.5)
        assert len(viewer.timings) - before <= 3  # not one refresh per move (200)
        verts, _ = viewer.bodies[0].evaluate()
        np.testing.assert_array_equal(viewer._nodes[0]["mesh"].vertices, verts.astype(np.float32))


@pytest.mark.parametrize(
    "origin, host, request_host, refused",
    [
        (None, "127.0.0.1", None, False),
        ("http://localhost:8080", "127.0.0.1", "localhost:8080", False),
        ("http://[::1]:8080", "127.0.0.1", "[::1]:8080", False),
        ("http://127.0.0.1:9999", "127.0.0.1", None, True),  # another local server's page
        ("http://evil.example:8080", "127.0.0.1", "evil.example:8080", True),  # DNS rebinding
        ("null", "127.0.0.1", None, True),
        ("http://10.0.0.5:8080", "0.0.0.0", "10.0.0.5:8080", False),  # served on the LAN, opened by IP
        ("http://10.0.0.6:8080", "0.0.0.0", "10.0.0.5:8080", True),
    ],
)
def test_origin_rules(origin, host, request_host, refused):
    gate = SessionGate(host=host, token="t0ken")
    assert (gate.reason_to_refuse(origin, "/t0ken", request_host, 8080) is not None) == refused
    assert gate.reason_to_refuse(origin, "/", request_host, 8080) == "no valid session token in the websocket URL"


@pytest.mark.filterwarnings("ignore:Queued a GuiUpdateMessage on a closed connection")  # viser: moves after close
def test_closing_during_a_burst_of_moves_stops_every_thread(tmp_path):
    viewer = Viewer(port=free_port(), out_dir=tmp_path, lighting="simple")
    slider = viewer.controls.betas[2]
    with _connect(viewer, None, viewer.gate.token) as ws:
        _send(ws, _camera())
        _received(ws, 1.0)
        for value in np.linspace(-3.0, 3.0, 500):
            _move(ws, slider, float(value))
        viewer.close()  # what Ctrl-C in `smplcore view` does
    assert not viewer._refresher.is_alive() and not viewer._player.is_alive()
    assert len(viewer._pending) <= 1  # merged: at most the last request was left undone
