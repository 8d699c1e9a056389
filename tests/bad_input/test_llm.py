"""Bad input and faults for the LLM spatial parser (agents/spatial/llm.py): one deadline per
request, headers included, and config settings refused before any request."""

import socket
import threading
import time

import pytest

from agents.spatial.llm import LLMParser, LLMParserConfig
from conceptfusion.errors import AgentError

# A deadline check, not a benchmark: a 1 s deadline must give up long before this.
_GENEROUS_S = 5.0


class _TrickleServer:
    """A loopback HTTP server that reads the request, then sends ``reply`` one byte every
    ``interval`` seconds (never finishing within a test) until stopped."""

    def __init__(self, reply: bytes, interval: float = 0.5):
        self.reply, self.interval = reply, interval
        self.stop = threading.Event()
        self.requests = 0
        self._sock = socket.socket()
        self._sock.bind(("127.0.0.1", 0))
        self._sock.listen(4)
        self._sock.settimeout(0.05)
        self.base_url = f"http://127.0.0.1:{self._sock.getsockname()[1]}/v1"
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        while not self.stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except (TimeoutError, OSError):
                continue
            threading.Thread(target=self._trickle, args=(conn,), daemon=True).start()

    def _trickle(self, conn):
        with conn:
            conn.settimeout(2.0)
            try:
                conn.recv(65536)  # the request (small enough for one read)
                self.requests += 1
                for i in range(len(self.reply)):
                    if self.stop.wait(self.interval):
                        return
                    conn.sendall(self.reply[i : i + 1])
                self.stop.wait()
            except OSError:  # the client gave up and closed
                return

    def close(self):
        self.stop.set()
        self._thread.join()
        self._sock.close()


@pytest.fixture
def trickle():
    servers = []

    def start(reply: bytes, interval: float = 0.5):
        servers.append(_TrickleServer(reply, interval))
        return servers[-1]

    yield start
    for s in servers:
        s.close()


def _parse_timed(base_url, **kw):
    parser = LLMParser(LLMParserConfig(base_url=base_url, retry_delay_s=0.0, **kw))
    t0 = time.monotonic()
    res = parser.parse("How far is the chair from the sofa?")
    return res, time.monotonic() - t0


def test_trickled_headers_hit_the_deadline(trickle):
    headers = b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\n" + b"X-Pad: " + b"a" * 10_000 + b"\r\n\r\n"
    server = trickle(headers)
    res, took = _parse_timed(server.base_url, timeout_s=1.0, max_retries=0)
    assert not res.ok
    assert res.reason == "LLM parser failed after 1 attempt(s): no reply within 1 s"
    assert took < _GENEROUS_S


def test_trickled_headers_with_retries_stay_bounded(trickle):
    server = trickle(b"HTTP/1.1 200 OK\r\n" + b"X-Pad: " + b"a" * 10_000)
    res, took = _parse_timed(server.base_url, timeout_s=0.5, max_retries=2)
    assert not res.ok and "after 3 attempt(s): no reply within 0.5 s" in res.reason
    assert server.requests == 3
    assert took < 3 * 0.5 + _GENEROUS_S


def test_trickled_body_hits_the_deadline(trickle):
    body = b'{"choices": [{"message": {"content": "howFar(chair, sofa)"}}]}' + b" " * 10_000
    reply = b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: %d\r\n\r\n" % len(body) + body
    server = trickle(reply, interval=0.01)  # headers arrive in ~1 s of a 1.5 s deadline, the body never does
    res, took = _parse_timed(server.base_url, timeout_s=1.5, max_retries=0)
    assert not res.ok
    assert "no reply within 1.5 s" in res.reason or "timed out while reading the reply" in res.reason
    assert took < _GENEROUS_S


def test_silent_server_after_accept_hits_the_deadline(trickle):
    server = trickle(b"", interval=0.5)  # reads the request, never answers
    res, took = _parse_timed(server.base_url, timeout_s=1.0, max_retries=0)
    assert not res.ok and res.reason.endswith("no reply within 1 s")
    assert took < _GENEROUS_S


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"base_url": "http://"}, r"base_url: expected a host"),
        ({"base_url": "http://:8080/v1"}, r"base_url: expected a host"),
        ({"base_url": "http://127.0.0.1:99999/v1"}, r"base_url: expected a port number"),
        ({"base_url": "http://127.0.0.1:abc/v1"}, r"base_url: expected a port number"),
        ({"base_url": "http://127.0.0.1:8080/v 1"}, r"base_url: expected no spaces or control characters"),
        ({"base_url": "http://127.0.0.1:8080/v1\n"}, r"base_url: expected no spaces or control characters"),
        ({"base_url": b"http://127.0.0.1/v1"}, r"base_url: expected an http:// or https:// URL"),
        ({"base_url": "ftp://127.0.0.1/v1"}, r"base_url: expected an http:// or https:// URL"),
        ({"base_url": "http://x", "timeout_s": 1e10}, r"timeout_s: expected at most 3600 s"),
        ({"base_url": "http://x", "retry_delay_s": 1e6}, r"retry_delay_s: expected at most 3600 s"),
        ({"base_url": "http://x", "timeout_s": float("inf")}, r"timeout_s: expected a finite number >= 0"),
        ({"base_url": "http://x", "timeout_s": True}, r"timeout_s: expected a finite number >= 0"),
        ({"base_url": "http://x", "max_tokens": 0}, r"max_tokens: expected an int >= 1"),
        ({"base_url": "http://x", "max_reply_bytes": "big"}, r"max_reply_bytes: expected an int >= 1"),
        ({"base_url": "http://x", "api_key": "sk-1\r\nX-Evil: 1"}, r"api_key: expected None or a non-empty str of printable ASCII"),
        ({"base_url": "http://x", "api_key": "ключ"}, r"api_key: expected None or a non-empty str of printable ASCII"),
        ({"base_url": "http://x", "api_key": ""}, r"api_key: expected None or a non-empty str"),
        ({"base_url": "http://x", "api_key": 123}, r"api_key: expected None or a non-empty str .* got int"),
        ({"base_url": "http://x", "model": None}, r"model: expected a non-empty str"),
    ],
)
def test_config_refuses_bad_settings(kwargs, message):
    with pytest.raises(AgentError, match=message):
        LLMParserConfig(**kwargs)


def test_parser_refuses_a_non_config():
    with pytest.raises(TypeError, match=r"config: expected an LLMParserConfig, got dict"):
        LLMParser({"base_url": "http://127.0.0.1:8080/v1"})


def test_question_of_the_wrong_type_is_refused():
    parser = LLMParser(LLMParserConfig(base_url="http://127.0.0.1:9/v1"))
    with pytest.raises(TypeError, match=r"question: expected a str, got bytes"):
        parser.parse(b"How far is the chair from the sofa?")


def test_api_key_with_a_space_is_refused_without_showing_it():
    with pytest.raises(AgentError, match=r"api_key: .* without whitespace, got a str of 9 characters with whitespace at index 4 \(the key is not shown\)") as info:
        LLMParserConfig(base_url="http://x", api_key="sk-1 abcd")
    assert "abcd" not in str(info.value)
