"""LLM spatial-question parser over the OpenAI-compatible chat-completions HTTP API.

Sends the paper's prompt (its appendix "Details on 3D spatial query modules") followed by the
question to ``POST {base_url}/chat/completions`` of a configurable server (a local llama.cpp or
vLLM server), and validates the reply against the eight signatures with
:func:`agents.spatial.signature.parse_signature`. Only the standard library is used.

Failure policy: a server that is unreachable, too slow, answers an HTTP error, or returns
something that is not exactly one known call with two arguments gives a cannot-parse
:class:`~agents.spatial.signature.ParseResult` carrying the reason (and a logged warning),
after at most ``1 + max_retries`` attempts each bounded by ``timeout_s``. It never raises for
server behaviour and never waits without bound.
"""

from __future__ import annotations

import http.client
import json
import logging
import math
import time
import urllib.error
import urllib.request
from dataclasses import dataclass

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


@dataclass(frozen=True)
class LLMParserConfig:
    """Where and how to reach the chat-completions server."""

    base_url: str
    """Server root including the API prefix, e.g. ``"http://127.0.0.1:8080/v1"``."""
    model: str = "default"
    """Model name sent in the request body (llama.cpp ignores it; vLLM needs the served name)."""
    timeout_s: float = 20.0
    """Upper bound on one attempt: connecting, waiting and reading the whole reply."""
    max_retries: int = 2
    """Further attempts after a failed one (timeouts, 5xx/429, unusable replies)."""
    retry_delay_s: float = 0.5
    """Pause between attempts."""
    temperature: float = 0.0
    """Sampling temperature (the paper used 0.7 with text-davinci-003; 0 makes parses repeatable)."""
    max_tokens: int = 64
    """Reply length cap; a signature is a handful of tokens."""
    api_key: str | None = None
    """Sent as a bearer token when set; local servers usually need none."""
    max_reply_bytes: int = 1_000_000
    """Replies longer than this are rejected as garbage."""

    def __post_init__(self) -> None:
        if not isinstance(self.base_url, str) or not self.base_url.startswith(("http://", "https://")):
            raise ValueError(f"base_url: expected an http:// or https:// URL, got {self.base_url!r}")
        if not isinstance(self.model, str) or not self.model:
            raise ValueError(f"model: expected a non-empty str, got {self.model!r}")
        for name in ("timeout_s", "retry_delay_s", "temperature"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")
        if self.timeout_s <= 0:
            raise ValueError(f"timeout_s: expected a number > 0, got {self.timeout_s!r}")
        for name in ("max_retries", "max_tokens", "max_reply_bytes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < (0 if name == "max_retries" else 1):
                raise ValueError(f"{name}: expected an int >= {0 if name == 'max_retries' else 1}, got {value!r}")

    @property
    def url(self) -> str:
        """The chat-completions endpoint."""
        return self.base_url.rstrip("/") + "/chat/completions"


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


def _reply_text(payload: bytes) -> str:
    try:
        data = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise _AttemptError(f"reply is not JSON ({err.__class__.__name__})", retry=True) from None
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
        with urllib.request.urlopen(request, timeout=config.timeout_s) as response:
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
