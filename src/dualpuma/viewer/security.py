"""What stands between the network and `dualpuma serve`: where it may listen, who may connect and
what a connected client may send.

* :func:`check_listen` — the host resolves, the port is a port, and it is free (or, with
  ``port="auto"``, the next free one), checked by binding it *before* viser starts: viser itself
  moves to the next port silently when one is taken, and hangs forever when it cannot bind at all.
* :class:`AccessPolicy` — the Host names this server answers to (a DNS-rebinding page has a foreign
  Host) and the same-origin rule for WebSocket handshakes (a page on another site has a foreign
  Origin). A handshake failing either is answered 403 before viser sees it.
* :func:`screen_message` — every message a client sends passes here before viser decodes it. Only
  the kinds the viewer uses pass (:data:`CLIENT_MESSAGES`: the camera, GUI updates, the gizmo);
  every other kind viser's client can send is dropped: the share tunnel (it would expose the server
  on a public relay), uploads, renders, forms (viser re-broadcast a form's "dirty" message to every
  client and kept each one for every later client: a client could fill the server's memory with
  them, 1 MB at a time). GUI updates may only carry a ``value`` (viser would otherwise let a client
  overwrite a handle's internal fields, e.g. its callbacks), and only a scalar one (bool, number,
  text: the viewer has no vector controls); strings are cut at :data:`MAX_TEXT` + 1 characters (so
  the viewer refuses them and nothing large is kept). A camera must be one a browser can have (a
  field of view of 0 or a window 0 pixels high divided by zero in the framing, which then failed on
  every frame, for every client); a gizmo's pose must be finite. Incoming messages are limited to
  :data:`MAX_MESSAGE_BYTES`, and a message nested too deeply to decode is dropped.
* :func:`start_server` — a ``viser.ViserServer`` built with the three above in place; every HTTP
  response also tells browsers not to show the page inside another site's frame (a page could
  otherwise lay the viewer under its own and have the user click its buttons).

viser 1.1.1 has no hook for any of this, so :func:`start_server` replaces
``websockets.asyncio.server.serve`` (the one call viser makes to open its socket) while the server
is being constructed, and only then: the replacement adds a ``process_request`` check in front of
viser's own HTTP handler and hands viser a connection whose ``recv`` screens messages.
"""

from __future__ import annotations

import errno
import http
import ipaddress
import math
import socket
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from urllib.parse import urlsplit

import msgspec
import viser
import websockets.asyncio.server as ws_server

from ..errors import ParameterError

__all__ = [
    "AUTO_PORT_START",
    "CLIENT_MESSAGES",
    "MAX_MESSAGE_BYTES",
    "MAX_TEXT",
    "AccessPolicy",
    "ScreenedConnection",
    "check_listen",
    "is_loopback",
    "screen_message",
    "start_server",
]

MAX_TEXT = 4096  #: longest string a client may send in a GUI update [characters]
MAX_MESSAGE_BYTES = 1 << 20  #: largest message a client may send [bytes]
AUTO_PORT_START = 8080  #: ``--port auto`` tries this port first, then the next ones
_AUTO_TRIES = 100
_LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
#: the kinds of client message the viewer uses; viser's client can send others (share tunnel, uploads,
#: renders, forms, pointer and scene-node clicks, commands, local storage), which are dropped
CLIENT_MESSAGES = frozenset({"ViewerCameraMessage", "GuiUpdateMessage", "TransformControlsUpdateMessage",
                             "TransformControlsDragStartMessage", "TransformControlsDragEndMessage"})
_MAX_PIXELS = 1 << 16  #: widest and tallest browser window a camera message may report [px]
#: every HTTP response: not to be shown inside another site's frame (clickjacking), types as sent
_RESPONSE_HEADERS = {"X-Frame-Options": "DENY", "Content-Security-Policy": "frame-ancestors 'none'",
                     "X-Content-Type-Options": "nosniff"}
_CONSTRUCT_LOCK = threading.Lock()  # one server is constructed at a time (the patch is process-wide)


def _addresses(host: str) -> list[ipaddress.IPv4Address | ipaddress.IPv6Address]:
    """The addresses ``host`` resolves to for listening (``127.1`` is 127.0.0.1, ``0`` is 0.0.0.0);
    [] if it does not resolve."""
    try:
        infos = socket.getaddrinfo(host.strip().strip("[]"), None, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        return [ipaddress.ip_address(str(i[4][0]).split("%")[0]) for i in infos]
    except (OSError, UnicodeError, ValueError):
        return []


def is_loopback(host: str) -> bool:
    """True if ``host`` is a loopback name or address, or resolves only to loopback addresses (only
    this machine can connect)."""
    h = host.strip().strip("[]").lower()
    if h in _LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(h).is_loopback
    except ValueError:
        addresses = _addresses(h) if h else []
        return bool(addresses) and all(a.is_loopback for a in addresses)


def _is_wildcard(host: str) -> bool:
    """``host`` means every interface (``0.0.0.0``, ``::``, ``0``, ``""``)."""
    return host in ("0.0.0.0", "::", "") or any(a.is_unspecified for a in _addresses(host))


def _bind_test(infos: list, port: int) -> OSError | None:
    """Bind every address ``host`` resolves to on ``port`` (as asyncio will); the first error."""
    for family, kind, proto, _, addr in infos:
        s = socket.socket(family, kind, proto)
        try:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as asyncio's create_server
            if family == socket.AF_INET6:
                s.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
            s.bind((addr[0], port, *addr[2:]))
        except OSError as exc:
            return exc
        finally:
            s.close()
    return None


def check_listen(host: object, port: object) -> int:
    """The port to listen on, after checking that ``host`` resolves and ``port`` can be bound.

    Args:
        host: a name or address of this machine.
        port: 0..65535 (0 = any free port) or ``"auto"`` (the first free port from
            :data:`AUTO_PORT_START` on).

    Raises:
        ParameterError: the host does not resolve or is not an address of this machine; the
            port is not a port number; the port is in use (the message says ``--port auto``).
    """
    if not isinstance(host, str) or not host or len(host) > 253 or any(c.isspace() for c in host):
        raise ParameterError(f"--host: expected a host name or address, got {host!r}"[:200])
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (socket.gaierror, UnicodeError) as exc:
        raise ParameterError(f"--host {host}: cannot be resolved ({getattr(exc, 'strerror', None) or exc})") from None
    auto = port == "auto"
    if auto:
        candidates: Iterable[int] = range(AUTO_PORT_START, AUTO_PORT_START + _AUTO_TRIES)
    else:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ParameterError(f"--port: expected a port number in [0, 65535] or 'auto', got {port!r}")
        candidates = (port,)
    last: OSError | None = None
    for p in candidates:
        last = _bind_test(infos, p)
        if last is None:
            return p
        if last.errno != errno.EADDRINUSE:
            break
    if last is not None and last.errno == errno.EADDRINUSE:
        if auto:
            raise ParameterError(f"--port auto: ports {AUTO_PORT_START}..{AUTO_PORT_START + _AUTO_TRIES - 1} "
                                 f"on {host} are all in use")
        raise ParameterError(f"--port {port}: already in use on {host} (another program, or another dualpuma "
                             "serve); choose another port or pass --port auto for the next free one")
    if last is not None and last.errno == errno.EADDRNOTAVAIL:
        raise ParameterError(f"--host {host}: not an address of this machine")
    raise ParameterError(f"cannot listen on {host}:{port}: {last.strerror if last else 'unknown error'}")


def _split_host(value: str) -> str | None:
    """The lower-case host name of a Host header or URL netloc (no port, no IPv6 brackets)."""
    try:
        name = urlsplit("//" + value).hostname
    except ValueError:
        return None
    return name.lower() if name else None


@dataclass(frozen=True, slots=True)
class AccessPolicy:
    """Who may talk to the server.

    Attributes:
        hosts: the host names and addresses (lower case, IPv6 without brackets) this server
            answers to in the HTTP ``Host`` header; anything else is a foreign page reaching it
            through DNS rebinding, and is refused.
    """

    hosts: frozenset[str]

    @classmethod
    def for_host(cls, host: str, extra: Iterable[str] = ()) -> AccessPolicy:
        """The policy of a server listening on ``host``: the loopback names, ``host`` itself, and
        for a wildcard host (``0.0.0.0``, ``::``) this machine's name and addresses; plus ``extra``
        (``--allow-host``: the names users type, e.g. behind a reverse proxy)."""
        names = set(_LOOPBACK_NAMES) | {host.strip("[]").lower()}
        if _is_wildcard(host):
            for n in {socket.gethostname(), socket.getfqdn()}:
                names.add(n.lower())
                try:
                    names.update(str(i[4][0]).lower() for i in socket.getaddrinfo(n, None))
                except OSError:
                    pass
        names.update(e.strip("[]").lower() for e in extra)
        return cls(frozenset(names))

    def host_ok(self, host_header: str | None) -> bool:
        """The request's Host header names this server."""
        return bool(host_header) and _split_host(str(host_header)) in self.hosts

    def origin_ok(self, origin: str | None, host_header: str) -> bool:
        """A browser's Origin is this very server (scheme http/https, same host:port); a client
        without an Origin header is not a browser page and is let through."""
        if origin is None:
            return True
        try:
            parts = urlsplit(origin)
        except ValueError:
            return False
        return parts.scheme in ("http", "https") and parts.netloc.lower() == host_header.lower()

    def refusal(self, headers) -> str | None:
        """Why a request with these headers is refused (None: accepted). WebSocket handshakes
        must pass both checks; plain HTTP requests the Host check."""
        hosts, origins = headers.get_all("Host"), headers.get_all("Origin")
        if len(hosts) != 1 or len(origins) > 1 or not self.host_ok(hosts[0]):
            return "Forbidden host"
        if headers.get("Upgrade", "").lower() == "websocket" and not self.origin_ok(origins[0] if origins else None, hosts[0]):
            return "Forbidden origin"
        return None


def screen_message(raw: object) -> bytes | None:
    """A client's raw message as viser may see it, or None to drop it (see the module docstring)."""
    if not isinstance(raw, bytes) or len(raw) > MAX_MESSAGE_BYTES:
        return None
    try:
        msg = msgspec.msgpack.decode(raw)
    except (msgspec.DecodeError, ValueError, TypeError, RecursionError):
        return None
    if not isinstance(msg, dict) or not isinstance(msg.get("type"), str) or msg["type"] not in CLIENT_MESSAGES:
        return None
    kind = msg["type"]
    if kind == "ViewerCameraMessage":
        return raw if _camera_ok(msg) else None
    if kind.startswith("TransformControls"):
        ok = isinstance(msg.get("name"), str) and len(msg["name"]) <= MAX_TEXT
        return raw if ok and (kind != "TransformControlsUpdateMessage" or _pose_ok(msg)) else None
    updates = msg.get("updates")
    if not isinstance(updates, dict) or set(updates) != {"value"}:
        return None
    value = updates["value"]
    if not isinstance(value, (bool, int, float, str)):  # every control of the viewer holds one scalar
        return None
    if isinstance(value, str) and len(value) > MAX_TEXT:
        updates["value"] = value[: MAX_TEXT + 1]  # still too long: the viewer refuses it
        return msgspec.msgpack.encode(msg)
    return raw


def _finite(value: object, n: int) -> bool:
    """``value`` is a list of ``n`` finite real numbers."""
    return (isinstance(value, list) and len(value) == n
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value))


def _pose_ok(msg: dict) -> bool:
    """A finite position and a finite, non-zero quaternion."""
    return _finite(msg.get("position"), 3) and _finite(msg.get("wxyz"), 4) and any(msg["wxyz"])


def _camera_ok(msg: dict) -> bool:
    """A camera a browser can have: a finite pose, a field of view in (0, pi), a positive window."""
    fov, near, far = msg.get("fov"), msg.get("near"), msg.get("far")
    size = [msg.get("image_height"), msg.get("image_width")]
    return (_pose_ok(msg) and _finite(msg.get("look_at"), 3) and _finite(msg.get("up_direction"), 3)
            and _finite([fov, near, far], 3) and 0.0 < fov < math.pi and 0.0 < near < far
            and _finite(size, 2) and all(float(v).is_integer() and 1 <= v <= _MAX_PIXELS for v in size))


class ScreenedConnection:
    """A websockets server connection whose :meth:`recv` passes :func:`screen_message`; every other
    attribute is the connection's own."""

    def __init__(self, connection) -> None:
        self._connection = connection

    def __getattr__(self, name: str):
        return getattr(self._connection, name)

    async def recv(self, *args, **kwargs):
        while True:
            out = screen_message(await self._connection.recv(*args, **kwargs))
            if out is not None:
                return out


def start_server(host: str, port: int, policy: AccessPolicy) -> viser.ViserServer:
    """A viser server on ``host:port`` guarded by ``policy`` and :func:`screen_message`.

    Raises:
        ParameterError: viser bound another port than ``port`` (taken meanwhile).
    """
    serve = ws_server.serve

    def guarded(handler, *args, process_request=None, **kwargs):
        async def screened_handler(connection):
            await handler(ScreenedConnection(connection))

        def checked(connection, request):
            why = policy.refusal(request.headers)
            if why is not None:
                return connection.respond(http.HTTPStatus.FORBIDDEN, why + "\n")
            return process_request(connection, request) if process_request is not None else None

        def framed(connection, request, response):
            for name, value in _RESPONSE_HEADERS.items():
                response.headers[name] = value
            return response

        kwargs["max_size"] = MAX_MESSAGE_BYTES
        return serve(screened_handler, *args, process_request=checked, process_response=framed, **kwargs)

    with _CONSTRUCT_LOCK:
        ws_server.serve = guarded
        try:
            server = viser.ViserServer(host=host, port=port, verbose=False)
        finally:
            ws_server.serve = serve
    if port != 0 and server.get_port() != port:
        got = server.get_port()
        server.stop()
        raise ParameterError(f"--port {port}: taken while starting (viser moved to {got}); try again or pass --port auto")
    return server
