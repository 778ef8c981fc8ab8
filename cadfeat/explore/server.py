"""The explorer's local HTTP server (standard library ``http.server``, bound to 127.0.0.1 only).

Routes (JSON in and out):

- ``GET /``: the page (``static/index.html``); ``GET /static/<file>``: its script and style;
  ``GET /vendor/<file>``: three.js r147 and OrbitControls (``cadfeat/report/vendor``, MIT) — nothing is
  fetched from anywhere else;
- ``GET /api/status``: the set-up's progress (``SetupStatus``: setting-up / ready / failed, the phase, the
  seconds so far, whether the set-up cache had it) — the server answers from the start, while the study is set
  up in the background (``SessionLoader``), and the page shows it until the study is ready;
- ``GET /api/scene``: ``ExploreSession.scene()`` (once per page load);
- ``POST /api/evaluate`` ``{"values": {name: value}, "pose": k}``: ``ExploreSession.evaluate``;
- ``POST /api/save-start`` ``{"values": ...}``: writes a new study TOML that starts at the design;
- ``POST /api/sweep`` ``{"values": ..., "name": variable, "n": 41}``: the objectives along one variable;
- ``POST /api/rebuild`` ``{"values": ...}``: the CAD model rebuilt at the design, as a mesh for the views;
- ``POST /api/export`` ``{"values": ...}``: CAD rebuild, ``design.step`` + ``design.glb`` into a new folder.

A bad request gets status 400 with ``{"error": message}``; a request that needs the study before its set-up is
done gets 503 with ``{"error": message, "status": ...}``. ``serve(session, port)`` (a ready ``ExploreSession`` or a
``SessionLoader``) returns a running ``ExploreServer`` (a daemon thread serves it); ``server.stop()`` shuts it
down and closes the socket.
"""

from __future__ import annotations

import json
import mimetypes
import sys
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cadfeat.errors import CadfeatError
from cadfeat.explore.loader import SessionLoader
from cadfeat.explore.status import NotReady

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.explore.session import ExploreSession

__all__ = ["ExploreServer", "serve"]

STATIC = Path(__file__).parent / "static"
VENDOR = Path(__file__).resolve().parents[1] / "report" / "vendor" / "three-0.147.0"
HOST = "127.0.0.1"
MAX_BODY = 1 << 20


class _Handler(BaseHTTPRequestHandler):
    server: ExploreServer
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the base class's name
        """Quiet: the terminal shows the URL and errors only."""

    def _send(self, status: int, body: bytes, ctype: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, status: int, data: Any) -> None:
        self._send(status, json.dumps(data, allow_nan=False).encode(), "application/json")

    def _file(self, folder: Path, name: str) -> None:
        path = (folder / name).resolve()
        if not name or path.parent != folder.resolve() or not path.is_file():
            self._json(HTTPStatus.NOT_FOUND, {"error": f"not found: {self.path}"})
            return
        ctype = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
        self._send(HTTPStatus.OK, path.read_bytes(), f"{ctype}; charset=utf-8" if ctype.startswith("text") or
                   ctype.endswith("javascript") else ctype)

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        route = self.path.split("?", 1)[0]
        if route in ("/", "/index.html"):
            self._file(STATIC, "index.html")
        elif route.startswith("/static/"):
            self._file(STATIC, route[len("/static/"):])
        elif route.startswith("/vendor/"):
            self._file(VENDOR, route[len("/vendor/"):])
        elif route == "/api/status":
            self._json(HTTPStatus.OK, self.server.loader.status.to_dict())
        elif route == "/api/scene":
            try:
                self._json(HTTPStatus.OK, self.server.scene())
            except NotReady as exc:
                self._not_ready(exc)
        else:
            self._json(HTTPStatus.NOT_FOUND, {"error": f"not found: {route}"})

    def _not_ready(self, exc: NotReady) -> None:
        self._json(HTTPStatus.SERVICE_UNAVAILABLE, {"error": str(exc), "status": exc.status.to_dict()})

    def do_POST(self) -> None:  # noqa: N802
        route = self.path.split("?", 1)[0]
        try:
            session = self.server.session
        except NotReady as exc:
            self.rfile.read(int(self.headers.get("Content-Length") or 0))
            self._not_ready(exc)
            return
        try:
            size = int(self.headers.get("Content-Length") or 0)
            if size > MAX_BODY:
                raise CadfeatError(f"request body of {size} bytes; allowed: at most {MAX_BODY}")
            body = json.loads(self.rfile.read(size) or b"{}")
            if not isinstance(body, dict):
                raise CadfeatError("the request body must be a JSON object")
            values = body.get("values")
            if route == "/api/evaluate":
                self._json(HTTPStatus.OK, session.evaluate(values, body.get("pose", 0)))
            elif route == "/api/save-start":
                self._json(HTTPStatus.OK, {"path": str(session.save_start(values))})
            elif route == "/api/sweep":
                self._json(HTTPStatus.OK, session.sweep(values, body.get("name"), body.get("n", 41)))
            elif route == "/api/rebuild":
                self._json(HTTPStatus.OK, {"mesh": session.rebuilt_mesh(values)})
            elif route == "/api/export":
                self._json(HTTPStatus.OK, session.export(values))
            else:
                self._json(HTTPStatus.NOT_FOUND, {"error": f"not found: {route}"})
        except (CadfeatError, ValueError) as exc:
            self._json(HTTPStatus.BAD_REQUEST, {"error": str(exc)})


class ExploreServer(ThreadingHTTPServer):
    """The HTTP server of one ``ExploreSession`` (daemon request threads)."""

    daemon_threads = True

    def __init__(self, session: ExploreSession | SessionLoader, port: int = 0) -> None:
        super().__init__((HOST, port), _Handler)
        self.loader = session if isinstance(session, SessionLoader) else SessionLoader.of(session)
        self._scene: bytes | None = None
        self._thread: threading.Thread | None = None

    @property
    def session(self) -> ExploreSession:
        """The ``ExploreSession``; ``NotReady`` while it is being set up (or when its set-up failed)."""
        return self.loader.session()

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A browser closing a kept-alive connection is not an error; anything else is printed as usual."""
        if not isinstance(sys.exc_info()[1], ConnectionError):
            super().handle_error(request, client_address)

    def scene(self) -> Any:
        if self._scene is None:
            self._scene = self.session.scene()
        return self._scene

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.server_address[1]}/"

    def start(self) -> ExploreServer:
        self._thread = threading.Thread(target=self.serve_forever, name="cadfeat-explore", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving, wait for the serving thread and close the socket."""
        if self._thread is not None:
            self.shutdown()
            self._thread.join(10.0)
        self.server_close()


def serve(session: ExploreSession | SessionLoader, port: int = 0) -> ExploreServer:
    """A started ``ExploreServer`` on 127.0.0.1:``port`` (0: a free port) of ``session`` (an ``ExploreSession``, or
    a ``SessionLoader`` setting one up)."""
    try:
        return ExploreServer(session, port).start()
    except OSError as exc:
        raise CadfeatError(f"explore: cannot listen on {HOST}:{port}: {exc.strerror or exc}; allowed: a free port "
                           "(--port N, 0 for any)") from None
