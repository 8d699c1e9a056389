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

One attempt is one HTTP request under one wall-clock deadline (:func:`agents.llm_http.request`).
Settings are checked when the config is built (:class:`~conceptfusion.errors.AgentError`).
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass

from agents.llm_http import AttemptError, chat_reply_text, check_client_settings, request
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
    """Sent as a bearer token when set (printable ASCII, no whitespace); local servers usually need none."""
    max_reply_bytes: int = 1_000_000
    """Replies longer than this are rejected as garbage."""

    def __post_init__(self) -> None:
        check_client_settings(self)

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


def _attempt(config: LLMParserConfig, body: bytes) -> str:
    payload = request(config.url, body=body, api_key=config.api_key, timeout_s=config.timeout_s,
                      max_reply_bytes=config.max_reply_bytes)
    return chat_reply_text(payload)


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
            except AttemptError as err:
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
