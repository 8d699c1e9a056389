"""The viewer's local web server: one page, its scripts, the map's points and the query endpoints.

It binds to the loopback interface only (``127.0.0.1``, ``localhost`` or ``::1``; any other host is
refused before a socket opens) and answers only requests addressed to it by such a name (the
``Host`` header), so a web page elsewhere cannot reach it through DNS rebinding. Files are served
from two places only: the packaged ``static/`` folder and the folder that holds the map; a path
that leaves them (``..``, an absolute path, a link pointing out) is refused with 403, a missing
file is 404. ``?map=NAME`` opens another map of the same folder.

Endpoints (``?map=`` optional on each ``/api`` one):

=====================  ======  ============================================================
``/``                  GET     the page (``static/index.html``)
``/static/PATH``       GET     the page's scripts, the vendored three.js
``/files/PATH``        GET     a file of the map's folder (a replay video beside the map); one
                              byte range (``Range: bytes=a-b``) answered 206, so a video seeks
``/api/info``          GET     map facts (:meth:`MapQueries.info`) and the folder's other maps
``/api/points``        GET     positions (M, 3) float32 then colours (M, 3) uint8
``/api/query``         POST    ``{"text": "red mug"}`` -> the answer (regions, heat, reason)
``/api/click``         POST    ``{"index": i}`` (a point of ``/api/points``) -> the answer
``/api/image``         POST    the bytes of an image file (``?name=`` for messages) -> the answer
=====================  ======  ============================================================

A bad query is answered with status 400 and ``{"ok": false, "error": "..."}``; the page shows it.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import re
import threading
import zipfile
from collections import OrderedDict
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, quote, unquote, urlsplit

from agents.builtin import make_mapper
from conceptfusion.errors import ConceptFusionError, HarnessError, MapFormatError, MissingFileError, UnknownNameError
from conceptfusion.map.persistence import FORMAT_NAME as MAP_FORMAT, read_map_meta
from conceptfusion.perception.registry import DEFAULT_ENCODER, ENCODERS
from conceptfusion.strict_json import loads_strict
from conceptfusion.perception.featurizer import ORACLE_ENCODERS, ORACLE_OPEN, encoder_name
from harness.report.paths import MAP_SUFFIX, VIDEO_SUFFIXES
from harness.viewer.queries import DEFAULT_MAX_POINTS, MAX_IMAGE_BYTES, BadQueryError, MapQueries

__all__ = ["LOOPBACK_HOSTS", "STATIC_DIR", "MapPerception", "ViewerServer", "check_loopback", "perception_for",
           "replay_video", "resolve_inside"]

LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")
"""Hosts the viewer may bind to."""
STATIC_DIR = Path(__file__).resolve().parent / "static"
"""The page, its script and the vendored three.js."""

_log = logging.getLogger(__name__)
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".css": "text/css",
          ".json": "application/json", ".png": "image/png", ".jpg": "image/jpeg", ".gif": "image/gif",
          ".mp4": "video/mp4", ".webm": "video/webm", ".txt": "text/plain; charset=utf-8"}
_CSP = ("default-src 'self'; img-src 'self' data: blob:; media-src 'self'; style-src 'self' 'unsafe-inline'; "
        "connect-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'")
_MAX_JSON_BYTES = 64 * 1024
_RANGE = re.compile(r"bytes=(\d*)-(\d*)")
_OPEN_MAPS = 2
_MAX_LISTED = 500


class _Refused(HarnessError):
    """An HTTP error answer: ``status`` and a message."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


def check_loopback(host: str) -> str:
    """``host`` when it names the loopback interface; otherwise ``HarnessError``."""
    if host not in LOOPBACK_HOSTS:
        raise HarnessError(f"viewer host: expected a loopback address ({', '.join(LOOPBACK_HOSTS)}), got {host!r}; "
                           "the viewer never serves other machines")
    return host


def resolve_inside(root: str | os.PathLike, rel: str) -> Path:
    """The existing file ``rel`` (a URL path, already unquoted) inside the folder ``root``.

    Raises ``PermissionError`` for a path that leaves ``root`` (``..`` segments, an absolute or
    drive path, a NUL byte, a link out of it) and ``FileNotFoundError`` for one that does not name
    a file there.
    """
    base = Path(root).resolve()
    parts = rel.replace("\\", "/").split("/")
    if "\0" in rel or rel.startswith("/") or ".." in parts or (parts and ":" in parts[0]):
        raise PermissionError(f"{rel!r}: expected a path inside the served folder")
    target = (base / rel).resolve()
    if target != base and base not in target.parents:
        raise PermissionError(f"{rel!r}: leads outside the served folder")
    if not target.is_file():
        raise FileNotFoundError(f"{rel!r}: no such file in the served folder")
    return target


class ViewerServer:
    """Serve one map (and its folder's other maps) to the browser.

    Args:
        map_path: the map file (``.npz`` from :func:`~conceptfusion.map.persistence.save_map`).
        encoder: perception spec whose text (and image) tower answers queries; it must be the
            one the map was built with (``embedded``, ``color``, ``oracle``, ``hf:...``). None
            (the default): the encoder each map file records (:func:`perception_for`), else
            :data:`~conceptfusion.perception.registry.DEFAULT_ENCODER`.
        host: a loopback address (see :data:`LOOPBACK_HOSTS`).
        port: TCP port; 0 picks a free one (see :attr:`url`).
        max_points: points sent to the browser at most.

    Raises:
        HarnessError: a host other than loopback; an encoder of another dimension than the map.
        MissingFileError, MapFormatError: the map cannot be read.
        UnknownNameError: an unknown encoder name.
    """

    def __init__(self, map_path: str | os.PathLike, *, encoder: str | None = None, host: str = "127.0.0.1",
                 port: int = 0, max_points: int = DEFAULT_MAX_POINTS) -> None:
        check_loopback(host)
        if isinstance(encoder, str) and encoder_name(encoder) == ORACLE_OPEN:
            raise HarnessError(f"--encoder {ORACLE_OPEN}: grounds descriptions in a live scene's ground truth (each "
                               "object's phrases), which a saved map does not keep, so the viewer cannot answer its queries")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise HarnessError(f"viewer port: expected an int in [0, 65535], got {port!r}")
        path = Path(map_path)
        if not path.exists():
            raise MissingFileError(f"map file not found: {path}")
        if not path.is_file():
            raise MapFormatError(f"{path}: expected a map file (.npz), got a folder")
        self.root, self.default_map = path.resolve().parent, path.resolve().name
        self.encoder, self.max_points = encoder, max_points
        self._maps: OrderedDict[str, MapQueries] = OrderedDict()
        self._maps_lock = threading.Lock()
        self.encoder_name = self.open_map(self.default_map).encoder_name  # fails here, before a socket opens, on a bad map or encoder
        server_cls = type("_Server", (ThreadingHTTPServer,), {"address_family": _family(host), "daemon_threads": True})
        self.httpd = server_cls((host, port), _handler(self))
        self.host, self.port = host, int(self.httpd.server_address[1])
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """The page's address, e.g. ``http://127.0.0.1:8765/``."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def allowed_host_header(self, value: str | None) -> bool:
        """Whether a request's ``Host`` header names this server by a loopback name."""
        names = {"127.0.0.1", "localhost", "[::1]"}
        return value in {f"{n}:{self.port}" for n in names} | names

    def open_map(self, name: str | None) -> MapQueries:
        """The opened map ``name`` of the folder (default: the one given), loaded on first use."""
        rel = self.default_map if not name else name
        target = resolve_inside(self.root, rel)
        key = target.relative_to(self.root).as_posix()
        with self._maps_lock:
            if key in self._maps:
                self._maps.move_to_end(key)
                return self._maps[key]
            how = perception_for(target, self.encoder)
            queries = MapQueries(target, how.mapper(), encoder_name=how.encoder, max_points=self.max_points,
                                 lookup=how.lookup, name_only=how.name_only, notes=how.notes)
            self._maps[key] = queries
            while len(self._maps) > _OPEN_MAPS:
                self._maps.popitem(last=False)
            return queries

    def sibling_maps(self) -> list[str]:
        """Map files of the folder, by name (``*.map.npz``, and other ``*.npz`` whose header says
        they are maps; at most the first few hundred are looked at)."""
        return sorted(p.name for p in sorted(self.root.glob("*.npz"))[:_MAX_LISTED] if _is_map_file(p))

    def start(self) -> "ViewerServer":
        """Serve in a background thread (tests, benchmarks); returns self."""
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="cf-viewer", daemon=True)
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        """Serve in this thread until :meth:`close` (or Ctrl-C)."""
        self.httpd.serve_forever()

    def close(self) -> None:
        """Stop serving and release the port."""
        self.httpd.shutdown()
        self.httpd.server_close()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def __enter__(self) -> "ViewerServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass(frozen=True)
class MapPerception:
    """How the viewer asks one map: the encoder and its score floor, the lookup, and notes for the
    page when these are not the ones the map file records."""

    encoder: str
    proposer: str = "rgbd"
    setting: str = "tabletop"
    min_score: tuple[float | None, ...] = ()
    """``(floor,)``: the floor the map records (None: no floor), applied when the map's own encoder
    answers; empty: the encoder's floor for :attr:`setting`."""
    lookup: str = "plain"
    name_only: bool = True
    notes: tuple[str, ...] = ()

    def mapper(self):
        """A :class:`~agents.concept_map.ConceptMapper` that asks as the map's agent did."""
        mapper = make_mapper(self.encoder, self.proposer, setting=self.setting)
        if self.min_score:
            mapper.config = dataclasses.replace(mapper.config, min_score=self.min_score[0])
        return mapper


def perception_for(map_path: str | os.PathLike, encoder: str | None = None) -> MapPerception:
    """How to ask the map at ``map_path``: with the encoder, floor and lookup its file records
    (:func:`~conceptfusion.map.persistence.read_map_meta`, written with the replays' maps), so the
    viewer's answers are the ones its agent saw; ``encoder`` (``--encoder``) overrides the
    recorded encoder, with a note when they differ. A map that records none is asked with
    :data:`~conceptfusion.perception.registry.DEFAULT_ENCODER` and a note saying so.

    Raises:
        UnknownNameError: the encoder (given or recorded) is not registered in this install; the
            message says where the name came from and how to add it (``--import``).
        MissingFileError, MapFormatError: the map's header cannot be read.
    """
    path = Path(map_path)
    meta = read_map_meta(path)
    recorded = meta.get("encoder")
    notes = []
    if encoder is None:
        encoder = recorded or DEFAULT_ENCODER
        if recorded is None:
            notes.append(f"the map file does not record its encoder; asked with {DEFAULT_ENCODER!r} "
                         "(pass --encoder when it was built with another)")
    elif recorded is not None and encoder != recorded:
        notes.append(f"asked with --encoder {encoder!r}, but the map was built with {recorded!r}: "
                     "answers may differ from its agent's")
    if encoder_name(encoder) not in ENCODERS and encoder_name(encoder) not in ORACLE_ENCODERS:
        source = "the map file records" if encoder == recorded else "--encoder names"
        raise UnknownNameError(f"{path.name}: {source} the encoder {encoder!r}, which this install does not have "
                               f"(registered: {', '.join(sorted(ENCODERS))}): --import the module that registers it "
                               "(conceptfusion.register_encoder), or pass --encoder")
    own = encoder == recorded
    return MapPerception(
        encoder=encoder, proposer=meta.get("proposer", "rgbd") if own else "rgbd",
        setting=meta.get("setting", "tabletop"), min_score=(meta["min_score"],) if own and "min_score" in meta else (),
        lookup=meta.get("lookup", "plain"), name_only=meta.get("name_only", True), notes=tuple(notes))


def _is_map_file(path: Path) -> bool:
    """Whether ``path`` is a map file, from its name or its header (cheap: no array is read)."""
    if not path.is_file():
        return False
    if path.name.endswith(MAP_SUFFIX):
        return True
    try:
        with zipfile.ZipFile(path) as z, z.open("header.npy") as f:
            raw = f.read(4096)  # the .npy preamble, then the JSON text of the map's header
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return False
    return f'"format": "{MAP_FORMAT}"'.encode() in raw


def replay_video(map_path: Path) -> Path | None:
    """The replay video beside a map (``<stem>.mp4``/``.gif`` for ``<stem>.map.npz`` or ``<stem>.npz``)."""
    name = map_path.name
    stem = name[: -len(MAP_SUFFIX)] if name.endswith(MAP_SUFFIX) else map_path.stem
    return next((map_path.with_name(stem + s) for s in VIDEO_SUFFIXES if map_path.with_name(stem + s).is_file()), None)


def _family(host: str):
    import socket

    return socket.AF_INET6 if ":" in host else socket.AF_INET


def _handler(viewer: ViewerServer):
    class Handler(BaseHTTPRequestHandler):
        server_version = "cf-viewer"
        protocol_version = "HTTP/1.1"

        def log_message(self, fmt, *args) -> None:  # library code logs, never prints
            _log.debug("%s " + fmt, self.address_string(), *args)

        # ---------------------------------------------------------- answers
        def _send(self, status: int, body: bytes, ctype: str, headers: dict | None = None) -> None:
            self.send_response(status)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(body)))
            for key, value in (headers or {}).items():
                self.send_header(key, value)
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.send_header("Content-Security-Policy", _CSP)
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(body)

        def _json(self, status: int, obj: dict) -> None:
            self._send(status, json.dumps(obj, allow_nan=False).encode("utf-8"), "application/json")

        def _error(self, status: int, message: str) -> None:
            self.close_connection = True  # an unread request body must not become the next request
            if self._path.startswith("/api/"):
                self._json(status, {"ok": False, "error": message})
            else:
                self._send(status, (message + "\n").encode("utf-8"), "text/plain; charset=utf-8")

        def _file(self, path: Path) -> None:
            """A whole file (200), or the one byte range a ``Range`` header asks for (206; a range
            past the end 416): a browser seeks in a video by ranges. Several ranges get the whole
            file, as HTTP allows."""
            body, ctype = path.read_bytes(), _TYPES.get(path.suffix.lower(), "application/octet-stream")
            size, match = len(body), _RANGE.fullmatch(self.headers.get("Range", "").strip())
            if match is None or match.groups() == ("", ""):
                return self._send(200, body, ctype, {"Accept-Ranges": "bytes"})
            first, last = match.groups()
            if first:
                start, end = int(first), min(int(last), size - 1) if last else size - 1
            else:  # "bytes=-N": the last N bytes
                start, end = max(size - int(last), 0), size - 1
            if start >= size or start > end:
                self.close_connection = True
                return self._send(416, b"", "text/plain; charset=utf-8", {"Content-Range": f"bytes */{size}"})
            self._send(206, body[start:end + 1], ctype, {"Accept-Ranges": "bytes", "Content-Range": f"bytes {start}-{end}/{size}"})

        # ---------------------------------------------------------- requests
        def _parse(self) -> None:
            parts = urlsplit(self.path)
            self._path = unquote(parts.path)
            self._query = {k: v[-1] for k, v in parse_qs(parts.query).items()}

        def _guarded(self, handle) -> None:
            self._path, self._query = "/", {}
            try:
                self._parse()
                if not viewer.allowed_host_header(self.headers.get("Host")):
                    raise _Refused(403, f"expected a request for this machine's loopback address, got Host "
                                        f"{self.headers.get('Host')!r}")
                handle()
            except _Refused as exc:
                self._error(exc.status, str(exc))
            except PermissionError as exc:
                self._error(403, str(exc))
            except FileNotFoundError as exc:
                self._error(404, str(exc))
            except (BadQueryError, ConceptFusionError, ValueError, TypeError) as exc:
                self._error(400, str(exc))
            except Exception as exc:  # the page gets a message, the server keeps serving
                _log.exception("viewer: %s %s failed", self.command, self.path)
                self._error(500, f"internal error: {type(exc).__name__}: {exc}")

        def do_GET(self) -> None:
            self._guarded(self._get)

        def do_HEAD(self) -> None:
            self._guarded(self._get)

        def do_POST(self) -> None:
            self._guarded(self._post)

        def _get(self) -> None:
            p = self._path
            if p in ("/", "/index.html"):
                return self._file(STATIC_DIR / "index.html")
            if p.startswith("/static/"):
                return self._file(resolve_inside(STATIC_DIR, p[len("/static/"):]))
            if p.startswith("/files/"):
                return self._file(resolve_inside(viewer.root, p[len("/files/"):]))
            if p == "/api/info":
                q = viewer.open_map(self._query.get("map"))
                info = q.info()
                video = replay_video(q.path)
                rel = q.path.relative_to(viewer.root).as_posix()
                return self._json(200, {"ok": True, **info, "map": rel, "maps": viewer.sibling_maps(),
                                        "replay": f"/files/{quote(video.relative_to(viewer.root).as_posix())}"
                                        if video else None})
            if p == "/api/points":
                return self._send(200, viewer.open_map(self._query.get("map")).points_payload(),
                                  "application/octet-stream")
            raise _Refused(404, f"{p!r}: no such page")

        def _body(self, limit: int) -> bytes:
            length = self.headers.get("Content-Length")
            if length is None or not length.isdigit():
                raise _Refused(411, "expected a request body with a Content-Length")
            if int(length) > limit:
                raise _Refused(413, f"expected at most {limit} bytes, got {length}")
            return self.rfile.read(int(length))

        def _json_body(self) -> dict:
            raw = self._body(_MAX_JSON_BYTES)
            try:
                obj = loads_strict(raw.decode("utf-8"), source="request body", error=BadQueryError)
            except BadQueryError:
                raise
            except (UnicodeDecodeError, ValueError):
                raise BadQueryError(f"expected a JSON object, got {raw[:40]!r}") from None
            if not isinstance(obj, dict):
                raise BadQueryError(f"expected a JSON object, got {type(obj).__name__}")
            return obj

        def _post(self) -> None:
            p = self._path
            if p == "/api/query":
                body = self._json_body()
                q = viewer.open_map(self._query.get("map"))
                return self._json(200, q.text(body.get("text"), lookup=body.get("lookup")))
            if p == "/api/click":
                body = self._json_body()
                q = viewer.open_map(self._query.get("map"))
                return self._json(200, q.click(body.get("index")))
            if p == "/api/image":
                data = self._body(MAX_IMAGE_BYTES)
                q = viewer.open_map(self._query.get("map"))
                return self._json(200, q.image(data, name=self._query.get("name", "image")[:80]))
            raise _Refused(404, f"{p!r}: no such endpoint")

    return Handler
