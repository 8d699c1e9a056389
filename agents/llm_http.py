"""One HTTP request to an OpenAI-compatible server under one wall-clock deadline (standard library only).

Shared by the clients of chat-completions servers (a local llama.cpp, vLLM or Ollama server): the
spatial-question parser (:mod:`agents.spatial.llm`) and the chat language planner
(:mod:`agents.instruct.chat`).

* :func:`request` - one GET or POST, bounded by one deadline; the reply's bytes, or
  :class:`AttemptError` with the reason and whether another attempt may help.
* :func:`chat_reply_text` - the assistant's text in a chat-completions reply.
* :func:`check_client_settings` - the settings both clients share, checked when their config is
  built (:class:`~conceptfusion.errors.AgentError`).

One attempt is one HTTP request under one wall-clock deadline, ``timeout_s`` after it starts:
connecting, sending, the status line and headers and the body all share it. Every socket read
and write gets the time left as its timeout, so a server that trickles its headers or body a
byte at a time is cut off at the deadline too. (Not bounded by it: name resolution, which is
the operating system's, and over ``https://`` each read of the TLS handshake gets the time left
when connecting rather than a share of one deadline; the servers this is for are local
``http://`` ones addressed by IP or ``localhost``.)
"""

from __future__ import annotations

import http.client
import io
import json
import math
import time
import urllib.error
import urllib.parse
import urllib.request

from conceptfusion.errors import AgentError
from conceptfusion.strict_json import loads_strict

__all__ = ["AttemptError", "ReplyError", "RETRY_STATUSES", "MAX_WAIT_S", "request", "chat_reply_text",
           "check_base_url", "check_api_key", "check_client_settings"]

RETRY_STATUSES = frozenset({408, 425, 429, 500, 502, 503, 504})
"""HTTP statuses another attempt may get past."""

MAX_WAIT_S = 3600.0
"""Longest ``timeout_s`` / ``retry_delay_s`` accepted (sockets refuse ~1e10 s)."""


class AttemptError(Exception):
    """One failed attempt; ``retry`` says whether another attempt may help, ``status`` is the
    HTTP status the server answered (None: no status, e.g. a timeout)."""

    def __init__(self, reason: str, *, retry: bool, status: int | None = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.retry = retry
        self.status = status


class ReplyError(AgentError):
    """A reply that is JSON but not one to read: nested too deeply, a key twice, a huge integer."""


def check_base_url(url: object) -> None:
    """Refuse a ``base_url`` that could never be requested: not http(s), no host, a bad port,
    or whitespace/control characters (:class:`~conceptfusion.errors.AgentError`)."""
    if not isinstance(url, str) or not url.startswith(("http://", "https://")):
        raise AgentError(f"base_url: expected an http:// or https:// URL, got {url!r}")
    if any(c.isspace() or not c.isprintable() for c in url):
        raise AgentError(f"base_url: expected no spaces or control characters, got {url!r}")
    parts = urllib.parse.urlsplit(url)
    if not parts.hostname:
        raise AgentError(f"base_url: expected a host (http://HOST[:PORT]/...), got {url!r}")
    try:
        parts.port
    except ValueError:
        raise AgentError(f"base_url: expected a port number in [0, 65535] after the host, got {url!r}") from None


def check_api_key(key: object) -> None:
    """Refuse an ``api_key`` that is not None or a non-empty str of printable ASCII without
    whitespace (a bearer token). The message says what is wrong without showing the key."""
    expected = "api_key: expected None or a non-empty str of printable ASCII characters without whitespace"
    if key is None:
        return
    if not isinstance(key, str):
        raise AgentError(f"{expected}, got {type(key).__name__}")
    if not key:
        raise AgentError(f"{expected}, got an empty str")
    bad = next((i for i, c in enumerate(key) if not (c.isascii() and c.isprintable()) or c.isspace()), None)
    if bad is not None:
        raise AgentError(f"{expected}, got a str of {len(key)} characters with {_kind_of(key[bad])} at index {bad} "
                         "(the key is not shown)")


def _kind_of(c: str) -> str:
    if c.isspace():
        return "whitespace"
    return "a control character" if not c.isprintable() else "a non-ASCII character"


def check_client_settings(config) -> None:
    """Check the settings every chat-completions client config has: ``base_url``, ``model``,
    ``timeout_s``, ``retry_delay_s``, ``temperature``, ``max_retries``, ``max_tokens``,
    ``max_reply_bytes`` and ``api_key``; :class:`~conceptfusion.errors.AgentError` naming the
    field and what arrived."""
    check_base_url(config.base_url)
    if not isinstance(config.model, str) or not config.model:
        raise AgentError(f"model: expected a non-empty str, got {config.model!r}")
    for name in ("timeout_s", "retry_delay_s", "temperature"):
        value = getattr(config, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise AgentError(f"{name}: expected a finite number >= 0, got {value!r}")
    if config.timeout_s <= 0:
        raise AgentError(f"timeout_s: expected a number > 0, got {config.timeout_s!r}")
    for name in ("timeout_s", "retry_delay_s"):
        if getattr(config, name) > MAX_WAIT_S:
            raise AgentError(f"{name}: expected at most {MAX_WAIT_S:g} s, got {getattr(config, name)!r}")
    for name in ("max_retries", "max_tokens", "max_reply_bytes"):
        value, low = getattr(config, name), 0 if name == "max_retries" else 1
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise AgentError(f"{name}: expected an int >= {low}, got {value!r}")
    check_api_key(config.api_key)


def _time_left(deadline: float) -> float:
    """Seconds until ``deadline`` (``time.monotonic``); ``TimeoutError`` once it has passed."""
    left = deadline - time.monotonic()
    if left <= 0:
        raise TimeoutError("the request deadline passed")
    return left


class _DeadlineReader(io.RawIOBase):
    """The socket's raw reader with the time left to the deadline as every read's timeout."""

    def __init__(self, raw, sock, deadline: float) -> None:
        super().__init__()
        self._raw, self._sock, self._deadline = raw, sock, deadline

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        self._sock.settimeout(_time_left(self._deadline))
        return self._raw.readinto(buffer)

    def close(self) -> None:
        self._raw.close()
        super().close()


class _DeadlineSocket:
    """A connected socket whose writes and the reader ``makefile`` gives share one deadline
    (``http.client`` reads the status line, headers and body through that reader)."""

    def __init__(self, sock, deadline: float) -> None:
        self._sock, self._deadline = sock, deadline

    def makefile(self, mode: str = "r", *args, **kwargs):
        if mode != "rb":  # http.client only reads "rb"
            return self._sock.makefile(mode, *args, **kwargs)
        raw = self._sock.makefile("rb", buffering=0)  # keeps the socket open while the reply is read
        return io.BufferedReader(_DeadlineReader(raw, self._sock, self._deadline))

    def sendall(self, data, *args) -> None:
        self._sock.settimeout(_time_left(self._deadline))
        self._sock.sendall(data, *args)

    def __getattr__(self, name: str):
        return getattr(self._sock, name)


class _DeadlineConnection:
    """Mixin for ``http.client`` connections: connect within the time left to ``deadline``,
    then read and write through a :class:`_DeadlineSocket`."""

    def __init__(self, *args, deadline: float, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._deadline = deadline

    def connect(self) -> None:
        self.timeout = _time_left(self._deadline)
        super().connect()
        self.sock = _DeadlineSocket(self.sock, self._deadline)


class _DeadlineHTTPConnection(_DeadlineConnection, http.client.HTTPConnection):
    pass


class _DeadlineHTTPSConnection(_DeadlineConnection, http.client.HTTPSConnection):
    pass


_DEADLINE_CONNECTIONS = {http.client.HTTPConnection: _DeadlineHTTPConnection, http.client.HTTPSConnection: _DeadlineHTTPSConnection}


class _DeadlineOpen:
    """Mixin for urllib's HTTP(S) handlers: open connections bounded by ``self.deadline``."""

    deadline: float

    def do_open(self, http_class, req, **kwargs):
        cls = _DEADLINE_CONNECTIONS[http_class]
        return super().do_open(lambda *a, **kw: cls(*a, deadline=self.deadline, **kw), req, **kwargs)


class _DeadlineHTTPHandler(_DeadlineOpen, urllib.request.HTTPHandler):
    pass


class _DeadlineHTTPSHandler(_DeadlineOpen, urllib.request.HTTPSHandler):
    pass


def _open_with_deadline(req: urllib.request.Request, deadline: float):
    """``urlopen(req)`` (proxies and redirects as urllib handles them) with every
    connection's reads and writes bounded by ``deadline``."""
    handlers = [_DeadlineHTTPHandler(), _DeadlineHTTPSHandler()]
    for h in handlers:
        h.deadline = deadline
    return urllib.request.build_opener(*handlers).open(req, timeout=_time_left(deadline))


def _read_bounded(response, deadline: float, limit: int) -> bytes:
    chunks, size = [], 0
    read = getattr(response, "read1", response.read)  # read1: one socket read, so the deadline is checked often
    while True:
        if time.monotonic() > deadline:
            raise AttemptError("timed out while reading the reply", retry=True)
        chunk = read(65536)
        if not chunk:
            return b"".join(chunks)
        size += len(chunk)
        if size > limit:
            raise AttemptError(f"reply longer than {limit} bytes", retry=True)
        chunks.append(chunk)


def request(url: str, *, body: bytes | None, api_key: str | None, timeout_s: float, max_reply_bytes: int) -> bytes:
    """One request to ``url`` - a POST of the JSON ``body``, or a GET when ``body`` is None - under
    one deadline ``timeout_s`` after it starts; the reply's bytes (at most ``max_reply_bytes``).

    Raises:
        AttemptError: the server is unreachable, too slow, answers an HTTP error status or a
            reply too long; ``retry`` says whether another attempt may help.
    """
    headers = {"Accept": "application/json"}
    if body is not None:
        headers["Content-Type"] = "application/json"
    if api_key:
        headers["Authorization"] = f"Bearer {api_key}"
    req = urllib.request.Request(url, data=body, headers=headers, method="GET" if body is None else "POST")
    deadline = time.monotonic() + timeout_s
    try:
        with _open_with_deadline(req, deadline) as response:
            return _read_bounded(response, deadline, max_reply_bytes)
    except urllib.error.HTTPError as err:
        err.close()
        raise AttemptError(f"server answered HTTP {err.code}", retry=err.code in RETRY_STATUSES, status=err.code) from None
    except urllib.error.URLError as err:
        reason = err.reason
        if isinstance(reason, TimeoutError):
            raise AttemptError(f"no reply within {timeout_s:g} s", retry=True) from None
        raise AttemptError(f"server unreachable ({reason})", retry=True) from None
    except TimeoutError:
        raise AttemptError(f"no reply within {timeout_s:g} s", retry=True) from None
    except (http.client.HTTPException, OSError) as err:
        raise AttemptError(f"connection failed ({err.__class__.__name__}: {err})", retry=True) from None


def chat_reply_text(payload: bytes) -> str:
    """The assistant's text in a chat-completions reply (``choices[0].message.content``, or a
    completions reply's ``choices[0].text``); :class:`AttemptError` (retry) for a reply that is
    not JSON to read (:func:`~conceptfusion.strict_json.loads_strict`) or has no text there."""
    try:
        data = loads_strict(payload.decode("utf-8"), source="reply", error=ReplyError)
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise AttemptError(f"reply is not JSON ({err.__class__.__name__})", retry=True) from None
    except ReplyError as err:
        raise AttemptError(f"reply refused: {err}", retry=True) from None
    try:
        choice = data["choices"][0]
        text = choice["message"]["content"] if "message" in choice else choice["text"]
    except (KeyError, IndexError, TypeError):
        raise AttemptError("reply has no choices[0].message.content", retry=True) from None
    if not isinstance(text, str):
        raise AttemptError("reply content is not text", retry=True)
    return text
