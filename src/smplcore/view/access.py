"""Who may talk to the viewer: a per-session token in the websocket URL, and the web origin of browser pages.

The viewer listens on 127.0.0.1, but any page open in the user's browser can open a websocket to
``ws://127.0.0.1:PORT`` (browsers do not apply the same-origin policy to websockets; they only say where the
page came from, in the ``Origin`` header). A client is let in only when

* its websocket path is ``/<token>``, a random token made for this session and printed by ``smplcore view``
  in the viewer's URL (``?websocket=ws://127.0.0.1:PORT/<token>``, which viser's page connects to), and
* it sends no ``Origin`` (not a browser page: a script of the same user), or the origin of a page this
  viewer served: ``http(s)://`` + a loopback name (``127.0.0.1``, ``localhost``, ``[::1]``), the ``--host``
  given, or the IP address the request was sent to, with the viewer's port. A DNS name other than
  ``localhost`` is refused, so a rebound domain (``evil.example`` resolving to 127.0.0.1) is too.

A refused client is disconnected (close code 1008, policy violation) before anything is sent to it or read
from it: it gets no mesh, cannot move a slider or press a button. viser offers no hook before the websocket
handshake completes, so the check runs in its first connection callback (viser runs those before it starts
sending to, or reading from, a client), reached through viser's ``_websock_server`` (checked on install).
What clients send is handled only for admitted clients: websockets still delivers the messages a refused
client sent before its connection closed.
"""

from __future__ import annotations

import asyncio
import ipaddress
import secrets
import threading
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote, urlsplit

__all__ = ["SessionGate"]

_LOOPBACK_NAMES = {"127.0.0.1", "localhost", "::1"}
POLICY_VIOLATION = 1008


@dataclass
class SessionGate:
    """The access check of one viewer session.

    Attributes
    ----------
    host : the address the server listens on.
    token : the session token (None: no token asked for, only the origin is checked).
    refused : ``(origin, path, reason)`` of every refused connection, newest last.
    """

    host: str = "127.0.0.1"
    token: str | None = field(default_factory=lambda: secrets.token_urlsafe(18))
    refused: list[tuple[str | None, str, str]] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _admitted: set[Any] = field(default_factory=set, repr=False)

    def url(self, port: int) -> str:
        """The address to open: the viewer's page, told which websocket (with the token) to connect to."""
        page = f"http://127.0.0.1:{port}/"
        if self.token is None:
            return page
        return page + "?websocket=" + quote(f"ws://127.0.0.1:{port}/{self.token}", safe="")

    def reason_to_refuse(self, origin: str | None, path: str, request_host: str | None, port: int) -> str | None:
        """Why a websocket with this ``Origin``, request path and ``Host`` header is refused, or None."""
        if self.token is not None and not secrets.compare_digest(path.split("?")[0].strip("/"), self.token):
            return "no valid session token in the websocket URL"
        if origin is None:
            return None
        try:
            parts = urlsplit(origin)
            origin_port = parts.port or {"http": 80, "https": 443}.get(parts.scheme)
        except ValueError:
            return f"malformed origin {origin!r}"
        name = (parts.hostname or "").lower()
        if parts.scheme not in ("http", "https") or origin_port != port:
            return f"foreign origin {origin!r}"
        allowed = set(_LOOPBACK_NAMES)
        if self.host not in ("0.0.0.0", "::", ""):
            allowed.add(self.host.lower().strip("[]"))
        served_to = _ip_literal(request_host)
        if served_to is not None:  # a page loaded from http://<the IP this request went to>:port
            allowed.add(served_to)
        if name not in allowed:
            return f"foreign origin {origin!r}"
        return None

    def install(self, server: Any) -> None:
        """Check every websocket client of a ``viser.ViserServer`` (and the ones already connected)."""
        infra = getattr(server, "_websock_server", None)
        if infra is None or not hasattr(infra, "_live_connections") or not hasattr(infra, "on_client_connect"):
            raise RuntimeError(
                "this viser version does not expose its websocket connections; the viewer cannot check "
                "who connects (viser 1.1 does)"
            )
        port = int(server.get_port())
        # Default deny for what clients send: a message is handled only from a client this gate admitted. (A
        # refused connection is closed, but websockets still delivers what arrived before the close frame.)
        serve = infra._handle_incoming_message

        async def guarded(client_id: Any, message: Any) -> None:
            if client_id in self._admitted:
                await serve(client_id, message)

        infra._handle_incoming_message = guarded

        async def check(client: Any) -> None:
            serve_client = client._handle_incoming_message

            async def guarded_client(client_id: Any, message: Any) -> None:
                if client_id in self._admitted:
                    await serve_client(client_id, message)

            client._handle_incoming_message = guarded_client
            connection = infra._live_connections.get(client.client_id)
            if connection is not None:
                await self._check(connection, client.client_id, port)

        def forget(client: Any) -> None:
            self._admitted.discard(client.client_id)

        infra.on_client_connect(check)
        infra.on_client_disconnect(forget)
        loop = getattr(infra, "_background_event_loop", None)
        for client_id, connection in list(infra._live_connections.items()):  # connected before the install
            if loop is not None:
                asyncio.run_coroutine_threadsafe(self._check(connection, client_id, port), loop)

    async def _check(self, connection: Any, client_id: Any, port: int) -> None:
        request = getattr(connection, "request", None)
        headers = getattr(request, "headers", {}) or {}
        origin = headers.get("Origin")
        path = str(getattr(request, "path", "") or "")
        reason = self.reason_to_refuse(origin, path, headers.get("Host"), port)
        if reason is None:
            self._admitted.add(client_id)
            return
        with self._lock:
            self.refused.append((origin, path.split("?")[0][:16], reason))
            del self.refused[:-100]
        await connection.close(POLICY_VIOLATION, "refused: " + reason[:100])


def _ip_literal(host_header: str | None) -> str | None:
    """The IP address in a ``Host`` header (``10.0.0.5:8080``, ``[::1]:8080``), or None for a name."""
    if not host_header:
        return None
    host = host_header.rsplit(":", 1)[0] if host_header.count(":") == 1 or "]" in host_header else host_header
    host = host.strip("[]")
    try:
        return str(ipaddress.ip_address(host))
    except ValueError:
        return None
