"""The study's local web server: Python's ThreadingHTTPServer, the pages shipped in
``ikbench/experiment/pages/`` (no file from anywhere else: the pages work offline), JSON in and
out, and one lock per experiment folder so two servers never write the same responses.

An app answers ``handle(method, path, query, body) -> Reply``; :class:`StudyServer` serves it
on ``host:port`` (127.0.0.1 unless told otherwise) in a background thread.
"""

from __future__ import annotations

import json
import threading
import urllib.parse
from collections.abc import Mapping
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, Protocol

from ikbench.core.errors import InputError

PAGES = Path(__file__).resolve().parent / "pages"
#: Content types of the shipped pages.
TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
         ".css": "text/css; charset=utf-8"}
#: The largest request body [bytes] (a response is a few hundred).
MAX_BODY_BYTES = 64 * 1024
LOCK_FILE = ".ikbench-play.lock"


@dataclass(frozen=True)
class Reply:
    """An HTTP reply."""

    status: int
    body: bytes
    content_type: str = "application/json"

    @classmethod
    def json(cls, value: Any, status: int = 200) -> Reply:
        return cls(status, json.dumps(value, separators=(",", ":")).encode())

    @classmethod
    def error(cls, status: int, message: str) -> Reply:
        return cls.json({"error": message}, status)


class App(Protocol):
    def handle(self, method: str, path: str, query: Mapping[str, str],
               body: Any) -> Reply: ...


def page(name: str) -> Reply:
    """A shipped page or script by file name; 404 for any other name."""
    path = PAGES / name
    if "/" in name or "\\" in name or name.startswith(".") or not path.is_file() \
            or path.suffix not in TYPES:
        return Reply.error(404, f"no page {name!r}")
    return Reply(200, path.read_bytes(), TYPES[path.suffix])


def _handler(app: App) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        server_version = "ikbench-experiment"

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - quiet
            return

        def _reply(self, reply: Reply) -> None:
            self.send_response(reply.status)
            self.send_header("Content-Type", reply.content_type)
            self.send_header("Content-Length", str(len(reply.body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(reply.body)

        def _serve(self, method: str) -> None:
            url = urllib.parse.urlsplit(self.path)
            query = {k: v[-1] for k, v in urllib.parse.parse_qs(url.query).items()}
            body: Any = None
            if method == "POST":
                length = int(self.headers.get("Content-Length") or 0)
                if length > MAX_BODY_BYTES:
                    self._reply(Reply.error(413, f"a request body of {length} bytes; at most "
                                                 f"{MAX_BODY_BYTES}"))
                    return
                try:
                    body = json.loads(self.rfile.read(length) or b"null")
                except (json.JSONDecodeError, UnicodeDecodeError):
                    self._reply(Reply.error(400, "the body is not JSON"))
                    return
            try:
                reply = app.handle(method, url.path, query, body)
            except InputError as exc:
                reply = Reply.error(400, str(exc))
            self._reply(reply)

        def do_GET(self) -> None:  # noqa: N802 - http.server's names
            self._serve("GET")

        def do_POST(self) -> None:  # noqa: N802
            self._serve("POST")

    return Handler


class StudyServer:
    """``app`` served on ``host:port`` in a daemon thread (port 0: any free one).

    Raises:
        InputError: the port is taken or the host cannot be bound.
    """

    def __init__(self, app: App, host: str = "127.0.0.1", port: int = 0):
        self.app = app
        try:
            self.httpd = ThreadingHTTPServer((host, port), _handler(app))
        except OSError as exc:
            reason = exc.strerror or exc
            raise InputError(f"--host {host} --port {port}: cannot listen there ({reason}); "
                             "give another --port") from None
        self.httpd.daemon_threads = True
        self.host, self.port = host, int(self.httpd.server_address[1])
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host
        return f"http://{host}:{self.port}/"

    def start(self) -> StudyServer:
        self._thread = threading.Thread(target=self.httpd.serve_forever, daemon=True,
                                        name="ikbench-experiment-server")
        self._thread.start()
        return self

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def __enter__(self) -> StudyServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


class FolderLock:
    """An exclusive lock on an experiment folder (``DIR/.ikbench-play.lock``, flock), held
    while a server records into it; the system releases it when the process ends, so a
    crashed server never blocks its restart.

    Raises:
        InputError: another process holds it.
    """

    def __init__(self, folder: Path):
        self.path = Path(folder) / LOCK_FILE
        self._stream: Any = None

    def acquire(self) -> FolderLock:
        try:
            import fcntl
        except ImportError:                 # not POSIX: no lock (stated in the docs)
            return self
        stream = self.path.open("a+")
        try:
            fcntl.flock(stream.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            stream.close()
            raise InputError(f"{self.path.parent}: another ikbench experiment run is recording "
                             "into this folder; stop it first (two writers could record a "
                             "trial twice)") from None
        self._stream = stream
        return self

    def release(self) -> None:
        if self._stream is not None:
            self._stream.close()
            self._stream = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
