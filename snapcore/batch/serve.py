"""``snapshot gallery OUT``: the batch gallery served, so that choices are saved at once.

A small standard-library HTTP server (:class:`http.server.ThreadingHTTPServer`) on this
machine: it serves the files of OUT as they are (the same static page that also works
from disk) and answers two requests of the page:

- ``GET /choices``: the thumbnail choices saved so far (``{"key": frame or null}``);
- ``POST /choices`` with such an object: each key must be a scene of the index and each
  frame a source frame of that clip (or null: back to the chosen pose); merged into
  ``OUT/thumb-choices.csv`` (:func:`snapcore.batch.choices.update_choices`), the other
  choices kept. A bad request changes nothing and gets one line saying why.

It listens on 127.0.0.1 by default, and refuses a POST from a page of another origin
(a site open in the same browser cannot write into OUT).
"""

from __future__ import annotations

import json
from functools import partial
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from snapcore.batch.choices import CHOICES_NAME, read_choices, update_choices
from snapcore.batch.discover import BatchError
from snapcore.batch.index import INDEX_NAME, read_index

__all__ = ["gallery_server", "check_choices", "MAX_BODY"]

#: Largest POST body read, bytes (a choice is some 60 bytes; 2,500 of them fit).
MAX_BODY = 1 << 20


def check_choices(doc, rows) -> dict[str, int | None]:
    """The choices in ``doc`` (parsed JSON), checked against the index ``rows``.

    Raises
    ------
    BatchError
        Not an object of scene keys to frames, a key not in the index, a frame that is
        not a source frame of that clip (the message names it).
    """
    if not isinstance(doc, dict) or not doc:
        raise BatchError("expected a JSON object of scene paths to frames")
    by_key = {r["path"]: r for r in rows}
    out: dict[str, int | None] = {}
    for key, frame in doc.items():
        row = by_key.get(key)
        if row is None:
            raise BatchError(f"{key}: not a scene of this gallery's index")
        if frame is None:
            out[key] = None
            continue
        if isinstance(frame, bool) or not isinstance(frame, int):
            raise BatchError(f"{key}: frame must be a whole number or null, got {frame!r}")
        first, n = row.get("first_frame"), row.get("n_frames")
        if row["status"] != "ok" or first is None or n is None:
            raise BatchError(f"{key}: the scene failed, it has no frames to choose from")
        if not first <= frame < first + n:
            raise BatchError(
                f"{key}: frame {frame} is not in the clip (source frames {first}..{first + n - 1})"
            )
        out[key] = frame
    return out


class _Handler(SimpleHTTPRequestHandler):
    """OUT's files, plus ``/choices``."""

    out: Path

    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        pass  # one line per picture of 2,500 cards would bury what matters

    def _json(self, status: HTTPStatus, doc) -> None:
        body = json.dumps(doc).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def end_headers(self):
        # the page and the index change with every run: never show a stale one
        if self.path.split("?")[0] in ("/", "/index.html", f"/{CHOICES_NAME}"):
            self.send_header("Cache-Control", "no-cache")
        super().end_headers()

    def do_GET(self):
        if self.path.split("?")[0] == "/choices":
            try:
                self._json(HTTPStatus.OK, read_choices(self.out))
            except BatchError as err:
                self._json(HTTPStatus.INTERNAL_SERVER_ERROR, {"error": str(err)})
            return
        super().do_GET()

    def do_POST(self):
        if self.path.split("?")[0] != "/choices":
            self._json(HTTPStatus.NOT_FOUND, {"error": f"{self.path}: nothing to post to"})
            return
        origin = self.headers.get("Origin")
        if origin is not None and origin != f"http://{self.headers.get('Host')}":
            self._json(HTTPStatus.FORBIDDEN, {"error": f"a page from {origin} may not save here"})
            return
        try:
            length = int(self.headers.get("Content-Length") or 0)
            if not 0 < length <= MAX_BODY:
                raise BatchError(f"the request body must be 1 to {MAX_BODY} bytes, got {length}")
            try:
                doc = json.loads(self.rfile.read(length))
            except (ValueError, UnicodeDecodeError) as err:
                raise BatchError(f"the request body is not JSON ({err})") from None
            changes = check_choices(doc, read_index(self.out / INDEX_NAME))
            update_choices(self.out, changes)
        except (BatchError, OSError, ValueError) as err:
            self._json(HTTPStatus.BAD_REQUEST, {"error": str(err).splitlines()[0]})
            return
        self._json(HTTPStatus.OK, {"saved": len(changes), "file": CHOICES_NAME})


def gallery_server(out, host: str = "127.0.0.1", port: int = 8765) -> ThreadingHTTPServer:
    """A server of the gallery in ``out`` (not started: call ``serve_forever``).

    Parameters
    ----------
    out : path-like
        A batch output folder (``index.html``, ``index.csv``).
    host : str
    port : int
        0: any free port (``server.server_address`` says which).

    Raises
    ------
    BatchError
        ``out`` holds no batch gallery.
    """
    out = Path(out).resolve()
    if not (out / "index.html").is_file() or not (out / INDEX_NAME).is_file():
        raise BatchError(f"{out}: no batch gallery here (run `snapshot batch ... -o {out}` first)")
    handler = type("GalleryHandler", (_Handler,), {"out": out})
    return ThreadingHTTPServer((host, port), partial(handler, directory=str(out)))
