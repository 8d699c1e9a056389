"""LLM spatial parser against a canned chat-completions server on 127.0.0.1."""

import json
import logging
import threading
from http.server import BaseHTTPRequestHandler

import pytest

from tests.agents.scripted_http import scripted_server
from agents.spatial.llm import PAPER_PROMPT, LLMParser, LLMParserConfig, build_request_body


class _Canned:
    """Replies the server hands out in order (the last one repeats), and what it received."""

    def __init__(self):
        self.replies = []
        self.requests = []  # (path, headers, json body)
        self.stop = threading.Event()


def _chat(content):
    return {"choices": [{"index": 0, "message": {"role": "assistant", "content": content}}]}


def _handler(canned):
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args):  # keep test output clean
            pass

        def do_POST(self):
            length = int(self.headers.get("Content-Length", 0))
            body = json.loads(self.rfile.read(length))
            canned.requests.append((self.path, dict(self.headers), body))
            index = min(len(canned.requests), len(canned.replies)) - 1
            kind, payload = canned.replies[index]
            if kind == "slow":
                canned.stop.wait(payload)  # cut short when the fixture stops the server
                return
            status, data = (200, json.dumps(payload).encode()) if kind == "json" else (payload, b"oops")
            if kind == "raw":
                status, data = 200, payload
            try:
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)
            except OSError:
                pass

    return Handler


@pytest.fixture
def server():
    canned = _Canned()
    with scripted_server(_handler(canned), canned.stop) as base_url:
        canned.base_url = base_url
        yield canned


def _parser(base_url, **kw):
    kw.setdefault("timeout_s", 2.0)
    kw.setdefault("retry_delay_s", 0.0)
    return LLMParser(LLMParserConfig(base_url=base_url, model="test-model", **kw))


def test_sends_the_paper_prompt_and_parses_the_reply(server):
    server.replies = [("json", _chat("howFar(refrigerator, television)"))]
    res = _parser(server.base_url).parse("What is the distance between the refrigerator and the TV?")
    assert res.ok and res.signature == "howFar(refrigerator, television)"
    assert res.confidence == 1.0  # a reply that parses as a call is taken at its word
    path, headers, body = server.requests[0]
    assert path == "/v1/chat/completions"
    assert headers["Content-Type"] == "application/json"
    assert "Authorization" not in headers
    assert body["model"] == "test-model"
    (message,) = body["messages"]
    assert message["role"] == "user"
    assert message["content"].startswith("Here is a set of available functions:\n1. howFar(object1, object2)")
    assert message["content"].endswith(
        "Query: How close is the chair from the sofa?\nResponse: howFar(chair, sofa)\n\n"
        "Query: What is the distance between the refrigerator and the TV?\nResponse:"
    )


def test_prompt_is_the_papers_text():
    lines = PAPER_PROMPT.splitlines()
    assert len(lines) == 13
    assert lines[5] == "5. onTopOf(object1, object2): returns true if object1 is on top of object 2"
    assert lines[9] == "Parse the provided queries into one of the above function formats."
    body = build_request_body(LLMParserConfig(base_url="http://x/v1"), "  Is the mug on the tray? ")
    assert body["messages"][0]["content"].endswith("Query: Is the mug on the tray?\nResponse:")


def test_reply_with_prefix_and_api_key(server):
    server.replies = [("json", _chat("Response: onTopOf(the apple, table)\n\nQuery: next"))]
    res = _parser(server.base_url, api_key="sk-local").parse("Is the apple on the table?")
    assert res.signature == "onTopOf(apple, table)"
    assert server.requests[0][1]["Authorization"] == "Bearer sk-local"


def test_server_error_is_retried_then_succeeds(server, caplog):
    server.replies = [("status", 500), ("json", _chat("under(rug, table)"))]
    with caplog.at_level(logging.WARNING, logger="agents.spatial.llm"):
        res = _parser(server.base_url, max_retries=2).parse("Is the rug under the table?")
    assert res.signature == "under(rug, table)"
    assert len(server.requests) == 2
    assert any("HTTP 500" in r.getMessage() for r in caplog.records)


def test_persistent_500_gives_up_after_the_retry_budget(server, caplog):
    server.replies = [("status", 500)]
    with caplog.at_level(logging.WARNING, logger="agents.spatial.llm"):
        res = _parser(server.base_url, max_retries=2).parse("Is the rug under the table?")
    assert not res.ok
    assert res.reason == "LLM parser failed after 3 attempt(s): server answered HTTP 500"
    assert len(server.requests) == 3
    assert len([r for r in caplog.records if r.levelno == logging.WARNING]) == 3


def test_client_error_is_not_retried(server):
    server.replies = [("status", 404)]
    res = _parser(server.base_url, max_retries=3).parse("Is the rug under the table?")
    assert not res.ok and "HTTP 404" in res.reason and "after 1 attempt" in res.reason
    assert len(server.requests) == 1


def test_slow_server_times_out(server):
    server.replies = [("slow", 30.0)]
    res = _parser(server.base_url, timeout_s=0.2, max_retries=1).parse("Is the rug under the table?")
    assert not res.ok and "no reply within 0.2 s" in res.reason
    assert len(server.requests) == 2  # bounded: one try plus one retry


@pytest.mark.parametrize(
    "reply, reason",
    [
        (("raw", b"<html>not json</html>"), "reply is not JSON"),
        (("json", {"error": "model not loaded"}), "no choices[0].message.content"),
        (("json", _chat("Sure! The chair is near the sofa.")), "no function call found"),
        (("json", _chat("isNear(chair, sofa)")), "unknown function 'isNear'"),
        (("json", _chat("howFar(chair, sofa, table)")), "exactly two arguments, got 3"),
        (("json", _chat(None)), "reply content is not text"),
    ],
)
def test_garbage_replies_are_cannot_parse(server, reply, reason):
    server.replies = [reply]
    res = _parser(server.base_url, max_retries=1).parse("How far is the chair from the sofa?")
    assert not res.ok and reason in res.reason and res.confidence == 0.0
    assert len(server.requests) == 2


def test_garbage_then_good_reply_recovers(server):
    server.replies = [("json", _chat("no idea")), ("json", _chat("isBigger(sofa, armchair)"))]
    res = _parser(server.base_url, max_retries=1).parse("Is the sofa bigger than the armchair?")
    assert res.signature == "isBigger(sofa, armchair)"


def test_oversized_reply_is_rejected(server):
    server.replies = [("json", _chat("howFar(a, b)" + " " * 5000))]
    res = _parser(server.base_url, max_retries=0, max_reply_bytes=1000).parse("How far is a from b?")
    assert not res.ok and "longer than 1000 bytes" in res.reason


def test_unreachable_server_is_cannot_parse():
    # bind a port, then close it: nothing listens there
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    res = _parser(f"http://127.0.0.1:{port}/v1", max_retries=1).parse("How far is the chair from the sofa?")
    assert not res.ok and "server unreachable" in res.reason and "after 2 attempt" in res.reason


def test_empty_question_makes_no_request(server):
    server.replies = [("json", _chat("howFar(a, b)"))]
    res = _parser(server.base_url).parse("   ")
    assert not res.ok and res.reason == "empty question"
    assert server.requests == []
    with pytest.raises(TypeError, match="question: expected a str"):
        _parser(server.base_url).parse(None)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"base_url": "127.0.0.1:8080"}, "base_url: expected an http"),
        ({"base_url": "http://x", "timeout_s": 0}, "timeout_s: expected a number > 0"),
        ({"base_url": "http://x", "max_retries": -1}, "max_retries: expected an int >= 0"),
        ({"base_url": "http://x", "max_retries": 1.5}, "max_retries"),
        ({"base_url": "http://x", "temperature": float("nan")}, "temperature"),
        ({"base_url": "http://x", "model": ""}, "model"),
    ],
)
def test_config_validation(kwargs, message):
    with pytest.raises(ValueError, match=message):
        LLMParserConfig(**kwargs)
