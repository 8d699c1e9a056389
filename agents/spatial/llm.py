"""LLM spatial-question parser over the OpenAI-compatible chat-completions HTTP API.

Sends the paper's prompt (its appendix "Details on 3D spatial query modules") followed by the
question to ``POST {base_url}/chat/completions`` of a configurable server (a local llama.cpp or
vLLM server), and validates the reply against the eight signatures with
:func:`agents.spatial.signature.parse_signature`. Only the standard library is used.

Failure policy: a server that is unreachable, too slow, answers an HTTP error, or returns
something that is not exactly one known call with two arguments (or a reply that is not JSON to
read: nested deeper than :data:`~conceptfusion.strict_json.MAX_JSON_DEPTH`, a key twice, a huge
integer; :func:`~conceptfusion.strict_json.loads_strict`) gives a cannot-parse
:class:`~agents.spatial.signature.ParseResult` carrying the reason (and a logged warning),
after at most ``1 + max_retries`` attempts each bounded by ``timeout_s``. It never raises for
server behaviour and never waits without bound.

Confidence: a reply that parses as one call gives that call with confidence 1.0 (the server is
asked for the call only, and a chat reply carries no measure of doubt to read; a backend that
returns token log-probabilities could give a graded one). A failure has confidence 0.

One attempt is one HTTP request under one wall-clock deadline, ``timeout_s`` after it starts:
connecting, sending, the status line and headers and the body all share it. Every socket read
and write gets the time left as its timeout, so a server that trickles its headers or body a
byte at a time is cut off at the deadline too. (Not bounded by it: name resolution, which is
the operating system's, and over ``https://`` each read of the TLS handshake gets the time left
when connecting rather than a share of one deadline; the servers this is for are local
``http://`` ones addressed by IP or ``localhost``.)
Settings are checked when the config is built (:class:`~conceptfusion.errors.AgentError`).
"""

from __future__ import annotations

import http.client
import io
import json
import logging
import math
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass

from conceptfusion.errors import AgentError
from conceptfusion.strict_json import loads_strict
from agents.spatial.signature import ParseResult, cannot_parse, parse_signature

__all__ = ["PAPER_PROMPT", "LLMParserConfig", "LLMParser", "build_request_body"]

_log = logging.getLogger(__name__)

PAPER_PROMPT = """Here is a set of available functions:
1. howFar(object1, object2): returns the distance between object1 and object2
2. isToTheRight(object1, object2): returns true if object1 is to the right of object2
3. isToTheLeft(object1, object2): returns true if object1 is to the left of object2
4. isContained(object1, object2): returns true if object1 is contained in object2
5. onTopOf(object1, object2): returns true if object1 is on top of object 2
6. under(object1, object2): returns true if object1 is underneath object 2
7. isBigger(object1, object2): returns true if object1 is bigger than object2
8. canFitInside(object1, object2): returns true if object1 can fit inside object2
Parse the provided queries into one of the above function formats.

Query: How close is the chair from the sofa?
Response: howFar(chair, sofa)"""
"""The paper's conditioning prompt, word for word (its typos "object 2" included)."""

_RETRY_STATUSES = {408, 425, 429, 500, 502, 503, 504}
_MAX_WAIT_S = 3600.0  # longest timeout_s / retry_delay_s accepted (sockets refuse ~1e10 s)


@dataclass(frozen=True)
class LLMParserConfig:
    """Where and how to reach the chat-completions server."""

    base_url: str
    """Server root including the API prefix, e.g. ``"http://127.0.0.1:8080/v1"``."""
    model: str = "default"
    """Model name sent in the request body (llama.cpp ignores it; vLLM needs the served name)."""
    timeout_s: float = 20.0
    """Upper bound on one attempt (one wall-clock deadline): connecting, sending, waiting, and
    reading the status line, headers and whole body. At most 3600 s."""
    max_retries: int = 2
    """Further attempts after a failed one (timeouts, 5xx/429, unusable replies)."""
    retry_delay_s: float = 0.5
    """Pause between attempts (at most 3600 s)."""
    temperature: float = 0.0
    """Sampling temperature (the paper used 0.7 with text-davinci-003; 0 makes parses repeatable)."""
    max_tokens: int = 64
    """Reply length cap; a signature is a handful of tokens."""
    api_key: str | None = None
    """Sent as a bearer token when set; local servers usually need none."""
    max_reply_bytes: int = 1_000_000
    """Replies longer than this are rejected as garbage."""

    def __post_init__(self) -> None:
        _check_base_url(self.base_url)
        if not isinstance(self.model, str) or not self.model:
            raise AgentError(f"model: expected a non-empty str, got {self.model!r}")
        for name in ("timeout_s", "retry_delay_s", "temperature"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise AgentError(f"{name}: expected a finite number >= 0, got {value!r}")
        if self.timeout_s <= 0:
            raise AgentError(f"timeout_s: expected a number > 0, got {self.timeout_s!r}")
        for name in ("timeout_s", "retry_delay_s"):
            if getattr(self, name) > _MAX_WAIT_S:
                raise AgentError(f"{name}: expected at most {_MAX_WAIT_S:g} s, got {getattr(self, name)!r}")
        for name in ("max_retries", "max_tokens", "max_reply_bytes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < (0 if name == "max_retries" else 1):
                raise AgentError(f"{name}: expected an int >= {0 if name == 'max_retries' else 1}, got {value!r}")
        if self.api_key is not None and (
            not isinstance(self.api_key, str) or not self.api_key or not (self.api_key.isascii() and self.api_key.isprintable())
        ):
            shown = type(self.api_key).__name__ if not isinstance(self.api_key, str) else "an empty str or one with other characters"
            raise AgentError(f"api_key: expected None or a non-empty str of printable ASCII characters, got {shown}")

    @property
    def url(self) -> str:
        """The chat-completions endpoint."""
        return self.base_url.rstrip("/") + "/chat/completions"


def _check_base_url(url: object) -> None:
    """Refuse a ``base_url`` that could never be requested: not http(s), no host, a bad port,
    or whitespace/control characters."""
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


def build_request_body(config: LLMParserConfig, question: str) -> dict:
    """The JSON body: the paper's prompt then ``Query: <question>`` / ``Response:``, one user turn."""
    content = f"{PAPER_PROMPT}\n\nQuery: {question.strip()}\nResponse:"
    return {
        "model": config.model,
        "messages": [{"role": "user", "content": content}],
        "temperature": config.temperature,
        "max_tokens": config.max_tokens,
        "stop": ["\nQuery:"],
    }


class _AttemptError(Exception):
    """One failed attempt; ``retry`` says whether another attempt may help."""

    def __init__(self, reason: str, *, retry: bool) -> None:
        super().__init__(reason)
        self.reason = reason
        self.retry = retry


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


def _open_with_deadline(request: urllib.request.Request, deadline: float):
    """``urlopen(request)`` (proxies and redirects as urllib handles them) with every
    connection's reads and writes bounded by ``deadline``."""
    handlers = [_DeadlineHTTPHandler(), _DeadlineHTTPSHandler()]
    for h in handlers:
        h.deadline = deadline
    return urllib.request.build_opener(*handlers).open(request, timeout=_time_left(deadline))


def _read_bounded(response, deadline: float, limit: int) -> bytes:
    chunks, size = [], 0
    read = getattr(response, "read1", response.read)  # read1: one socket read, so the deadline is checked often
    while True:
        if time.monotonic() > deadline:
            raise _AttemptError("timed out while reading the reply", retry=True)
        chunk = read(65536)
        if not chunk:
            return b"".join(chunks)
        size += len(chunk)
        if size > limit:
            raise _AttemptError(f"reply longer than {limit} bytes", retry=True)
        chunks.append(chunk)


class _ReplyError(AgentError):
    """A reply that is JSON but not one to read: nested too deeply, a key twice, a huge integer."""


def _reply_text(payload: bytes) -> str:
    try:
        data = loads_strict(payload.decode("utf-8"), source="reply", error=_ReplyError)
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise _AttemptError(f"reply is not JSON ({err.__class__.__name__})", retry=True) from None
    except _ReplyError as err:
        raise _AttemptError(f"reply refused: {err}", retry=True) from None
    try:
        choice = data["choices"][0]
        text = choice["message"]["content"] if "message" in choice else choice["text"]
    except (KeyError, IndexError, TypeError):
        raise _AttemptError("reply has no choices[0].message.content", retry=True) from None
    if not isinstance(text, str):
        raise _AttemptError("reply content is not text", retry=True)
    return text


def _attempt(config: LLMParserConfig, body: bytes) -> str:
    headers = {"Content-Type": "application/json", "Accept": "application/json"}
    if config.api_key:
        headers["Authorization"] = f"Bearer {config.api_key}"
    request = urllib.request.Request(config.url, data=body, headers=headers, method="POST")
    deadline = time.monotonic() + config.timeout_s
    try:
        with _open_with_deadline(request, deadline) as response:
            payload = _read_bounded(response, deadline, config.max_reply_bytes)
    except urllib.error.HTTPError as err:
        err.close()
        raise _AttemptError(f"server answered HTTP {err.code}", retry=err.code in _RETRY_STATUSES) from None
    except urllib.error.URLError as err:
        reason = err.reason
        if isinstance(reason, TimeoutError):
            raise _AttemptError(f"no reply within {config.timeout_s:g} s", retry=True) from None
        raise _AttemptError(f"server unreachable ({reason})", retry=True) from None
    except TimeoutError:
        raise _AttemptError(f"no reply within {config.timeout_s:g} s", retry=True) from None
    except (http.client.HTTPException, OSError) as err:
        raise _AttemptError(f"connection failed ({err.__class__.__name__}: {err})", retry=True) from None
    return _reply_text(payload)


@dataclass(frozen=True)
class LLMParser:
    """A :class:`~agents.spatial.signature.SpatialQuestionParser` backed by a chat-completions server."""

    config: LLMParserConfig
    """Server address, timeout and retry policy."""

    def __post_init__(self) -> None:
        if not isinstance(self.config, LLMParserConfig):
            raise TypeError(f"config: expected an LLMParserConfig, got {type(self.config).__name__}")

    def parse(self, question: str) -> ParseResult:
        """Ask the server to parse ``question``; a cannot-parse result on any failure."""
        if not isinstance(question, str):
            raise TypeError(f"question: expected a str, got {type(question).__name__}")
        if not question.strip():
            return cannot_parse("empty question")
        body = json.dumps(build_request_body(self.config, question)).encode("utf-8")
        attempts = 1 + self.config.max_retries
        reason = "no attempt made"
        for attempt in range(1, attempts + 1):
            try:
                text = _attempt(self.config, body)
            except _AttemptError as err:
                reason, retry = err.reason, err.retry
            else:
                result = parse_signature(text)
                if result.ok:
                    return result
                reason, retry = f"unusable reply: {result.reason}", True
            _log.warning("LLM parse attempt %d/%d for %r failed: %s", attempt, attempts, question, reason)
            if not retry:
                break
            if attempt < attempts and self.config.retry_delay_s > 0:
                time.sleep(self.config.retry_delay_s)
        return cannot_parse(f"LLM parser failed after {attempt} attempt(s): {reason}")
