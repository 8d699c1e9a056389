"""The chat language planner against a scripted chat-completions server on 127.0.0.1."""

import json
import socket
import threading
from http.server import BaseHTTPRequestHandler

import pytest

from tests.agents.scripted_http import scripted_server
from agents.instruct.chat import PLANNER_PROMPT, ChatPlanner, ChatPlannerConfig
from agents.instruct.planner import GoalQuery, MapObject, PlannerContext, make_planner
from conceptfusion.errors import AgentError
from conceptfusion.spatial.comparators import COMPARATOR_NAMES


class _Script:
    """Replies the server hands out in order (the last one repeats), and what it received."""

    def __init__(self):
        self.replies = []  # ("reply", dict the model "writes") | ("text", str) | ("raw", bytes) | ("status", int) | ("slow", s)
        self.models = (200, {"object": "list", "data": [{"id": "test-model"}]})
        self.requests = []  # (path, headers, json body)
        self.gets = []  # (path, headers)
        self.stop = threading.Event()


def _chat(content):
    return json.dumps({"choices": [{"index": 0, "message": {"role": "assistant", "content": content}}]}).encode()


def _handler(script):
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def _send(self, status, data):
            try:
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)
            except OSError:
                pass

        def do_GET(self):
            script.gets.append((self.path, dict(self.headers)))
            status, payload = script.models
            self._send(status, json.dumps(payload).encode())

        def do_POST(self):
            body = json.loads(self.rfile.read(int(self.headers.get("Content-Length", 0))))
            script.requests.append((self.path, dict(self.headers), body))
            kind, payload = script.replies[min(len(script.requests), len(script.replies)) - 1]
            if kind == "slow":
                script.stop.wait(payload)  # cut short when the fixture stops the server
                return
            if kind == "status":
                self._send(payload, b"oops")
            elif kind == "raw":
                self._send(200, payload)
            else:
                self._send(200, _chat(json.dumps(payload) if kind == "reply" else payload))

    return Handler


@pytest.fixture
def server():
    script = _Script()
    with scripted_server(_handler(script), script.stop) as base_url:
        script.base_url = base_url
        yield script


def _planner(base_url, **kw):
    kw.setdefault("timeout_s", 2.0)
    kw.setdefault("retry_delay_s", 0.0)
    kw.setdefault("max_retries", 0)
    return ChatPlanner(ChatPlannerConfig(base_url=base_url, model="test-model", **kw))


def _task(body, index=0):
    """The part of a user turn after the prompt (the prompt's own example lists objects too)."""
    return body["messages"][index]["content"].split("Now your task.", 1)[1]


ROOMS = ("kitchen", "living room", "bedroom")
OBJECTS = (MapObject("sofa", (1.0, 2.0, 0.4), "living room"), MapObject("coffee table", (1.3, 1.4, 0.2), "living room"),
           MapObject("mug", (4.0, 0.5, 0.9), "kitchen"), MapObject("dining table", (4.1, 0.6, 0.4), "kitchen"))


class _Map:
    """A fake ``ask`` that records its calls."""

    def __init__(self, answers):
        self.answers, self.calls = answers, []

    def __call__(self, function, a, b):
        self.calls.append((function, a, b))
        return self.answers[(function, a, b)]


def _map_context(answers=None):
    fake = _Map(answers or {})
    return PlannerContext(rooms=ROOMS, objects=OBJECTS, ask=fake), fake


NO_MAP = PlannerContext(rooms=ROOMS)


def test_goals_without_a_map(server):
    server.replies = [("reply", {"questions": [], "goals": [{"phrase": "apple", "room": "Kitchen"}, {"phrase": "banana", "room": None}],
                                 "reasoning": "Fruit is kept in the kitchen."})]
    proposal = _planner(server.base_url).propose("Find me something to eat.", NO_MAP)
    assert proposal.failure is None
    assert proposal.goals == (GoalQuery("apple", "kitchen"), GoalQuery("banana"))  # the plan's spelling of the room
    assert proposal.reasoning == "Fruit is kept in the kitchen."
    assert proposal.questions == ()
    path, headers, body = server.requests[0]
    assert path == "/v1/chat/completions" and headers["Content-Type"] == "application/json"
    assert "Authorization" not in headers
    assert body["model"] == "test-model" and body["temperature"] == 0.0 and body["max_tokens"] == 512
    assert "response_format" not in body
    (message,) = body["messages"]
    assert message["role"] == "user" and message["content"].startswith(PLANNER_PROMPT)
    task = _task(body)
    assert "Instruction: Find me something to eat." in task
    assert "Rooms: kitchen, living room, bedroom" in task
    assert "Objects in the map" not in task and "sofa" not in task
    assert "do not ask questions" in task


def test_questions_then_goals_with_a_map(server):
    context, fake = _map_context({("howFar", "sofa", "coffee table"): 0.4, ("onTopOf", "mug", "dining table"): True})
    server.replies = [
        ("reply", {"questions": [{"function": "howFar", "a": "sofa", "b": "Coffee Table"},
                                 {"function": "ONTOPOF", "a": "mug", "b": "dining table"}],
                   "goals": [], "reasoning": "Check what is near the coffee table."}),
        ("reply", {"goals": [{"phrase": "sofa", "room": "living room"}], "reasoning": "The sofa is next to it."}),
    ]
    proposal = _planner(server.base_url, api_key="sk-local").propose("I want to sit by the coffee table.", context)
    assert proposal.failure is None
    assert proposal.goals == (GoalQuery("sofa", "living room"),)
    assert fake.calls == [("howFar", "sofa", "coffee table"), ("onTopOf", "mug", "dining table")]  # the map's spellings
    assert proposal.questions == ("howFar(sofa, coffee table) -> 0.40 m", "onTopOf(mug, dining table) -> true")
    assert proposal.reasoning == "Check what is near the coffee table.\nThe sofa is next to it."
    assert len(server.requests) == 2
    first, second = server.requests[0][2], server.requests[1][2]
    assert server.requests[1][1]["Authorization"] == "Bearer sk-local"
    task = _task(first)
    assert "Objects in the map:\n- sofa (living room, at 1.0, 2.0)\n- coffee table (living room, at 1.3, 1.4)" in task
    assert "- mug (kitchen, at 4.0, 0.5)" in task and "Instruction: I want to sit by the coffee table." in task
    assert [m["role"] for m in second["messages"]] == ["user", "assistant", "user"]
    assert second["messages"][0] == first["messages"][0]
    assert json.loads(second["messages"][1]["content"])["reasoning"] == "Check what is near the coffee table."
    assert second["messages"][2]["content"] == ("Answers from the map:\nhowFar(sofa, coffee table) -> 0.40 m\n"
                                               "onTopOf(mug, dining table) -> true\nReply in the same JSON format.")


def test_a_fenced_reply_and_an_empty_map(server):
    server.replies = [("text", 'Here you go:\n```json\n{"questions": [], "goals": ["mug"], "reasoning": ""}\n```')]
    context = PlannerContext(rooms=ROOMS, objects=(), ask=_Map({}))
    proposal = _planner(server.base_url, json_mode=True).propose("Find a mug.", context)
    assert proposal.failure is None and proposal.goals == (GoalQuery("mug"),)
    body = server.requests[0][2]
    assert body["response_format"] == {"type": "json_object"}
    assert "Objects in the map: none yet" in _task(body)


def test_neither_goals_nor_questions_is_no_goals_without_failure(server):
    server.replies = [("reply", {"questions": [], "goals": [], "reasoning": "Nothing fits yet; explore."})]
    proposal = _planner(server.base_url).propose("Find the cat's toy.", _map_context()[0])
    assert proposal.failure is None and proposal.goals == () and proposal.reasoning == "Nothing fits yet; explore."


@pytest.mark.parametrize(
    "reply, reason",
    [
        (("text", '{"goals": [{"phrase": "mug"'), "unusable reply in round 1: reply is not JSON (Expecting"),
        (("text", "I would look for a mug."), "unusable reply in round 1: reply is not a JSON object (got 'I would"),
        (("text", '{"goals": [], "goals": []}'), "reply refused: planner reply:line 1: duplicate key 'goals'"),
        (("reply", {"questions": [], "reasoning": "hmm"}), 'unusable reply in round 1: reply has no "goals" list'),
        (("reply", {"goals": "mug"}), 'reply has no "goals" list (got str)'),
        (("reply", {"goals": [{"phrase": "mug; rm -rf /"}]}), "goal 1: goal phrase: expected 1 to 60 letters"),
        (("reply", {"goals": [{"phrase": "x" * 61}]}), "goal 1: goal phrase: expected 1 to 60"),
        (("reply", {"goals": [{"room": "kitchen"}]}), 'goal 1: expected {"phrase": ..., "room": ...}'),
        (("reply", {"goals": [{"phrase": "mug", "room": "garage"}]}),
         "goal 1: room 'garage' is not one of the rooms (kitchen, living room, bedroom)"),
        (("reply", {"goals": [], "questions": [{"function": "isNear", "a": "sofa", "b": "mug"}]}),
         "question 1: unknown comparator 'isNear' (known: howFar, isToTheRight"),
        (("reply", {"goals": [], "questions": [{"function": "howFar", "a": "sofa", "b": "spoon"}]}),
         "question 1: 'spoon' is not an object in the map"),
        (("reply", {"goals": [], "questions": [{"function": "howFar", "a": "sofa"}]}), 'question 1: expected {"function"'),
        (("reply", {"goals": [], "reasoning": 3}), 'reply "reasoning" is not text (got int)'),
    ],
)
def test_unusable_replies_are_failures_not_retried(server, reply, reason):
    server.replies = [reply]
    context, fake = _map_context()
    proposal = _planner(server.base_url, max_retries=2).propose("Find a mug.", context)
    assert proposal.goals == () and reason in proposal.failure
    assert fake.calls == []
    assert len(server.requests) == 1  # the model's own answer: asking again at temperature 0 gets the same


def test_questions_without_a_map_are_refused(server):
    server.replies = [("reply", {"goals": [], "questions": [{"function": "howFar", "a": "sofa", "b": "mug"}],
                                 "reasoning": "Where are they?"})]
    proposal = _planner(server.base_url).propose("Find a mug.", NO_MAP)
    assert proposal.failure == "unusable reply in round 1: questions asked without a map (only goals are allowed)"
    assert proposal.reasoning == "Where are they?"


def test_too_many_rounds_is_a_failure_keeping_the_questions(server):
    context, fake = _map_context({("isBigger", "sofa", "mug"): False})
    server.replies = [("reply", {"goals": [], "questions": [{"function": "isBigger", "a": "sofa", "b": "mug"}]})]
    proposal = _planner(server.base_url, max_rounds=1).propose("Find a mug.", context)
    assert proposal.failure == "still asking questions after 1 round(s) of answers (max_rounds=1)"
    assert proposal.questions == ("isBigger(sofa, mug) -> false",)
    assert len(fake.calls) == 1 and len(server.requests) == 2


def test_not_found_and_numpy_answers_are_written_out(server):
    np = pytest.importorskip("numpy")
    context, _ = _map_context({("under", "mug", "sofa"): None, ("isContained", "mug", "sofa"): np.bool_(True)})
    server.replies = [("reply", {"goals": [], "questions": [{"function": "under", "a": "mug", "b": "sofa"},
                                                            {"function": "isContained", "a": "mug", "b": "sofa"}]}),
                      ("reply", {"goals": ["mug"]})]
    proposal = _planner(server.base_url).propose("Find a mug.", context)
    assert proposal.questions == ("under(mug, sofa) -> not found in the map", "isContained(mug, sofa) -> true")


def test_slow_server_is_a_timeout_failure(server):
    server.replies = [("slow", 30.0)]
    proposal = _planner(server.base_url, timeout_s=0.3, max_retries=1).propose("Find a mug.", NO_MAP)
    assert proposal.goals == ()
    assert proposal.failure == "chat server failed after 2 attempt(s): no reply within 0.3 s"
    assert len(server.requests) == 2  # bounded: one try plus one retry


def test_http_500_is_retried_then_a_failure(server):
    server.replies = [("status", 500)]
    proposal = _planner(server.base_url, max_retries=1).propose("Find a mug.", NO_MAP)
    assert proposal.failure == "chat server failed after 2 attempt(s): server answered HTTP 500"
    assert len(server.requests) == 2


def test_http_500_then_a_reply_recovers(server):
    server.replies = [("status", 503), ("reply", {"goals": ["mug"]})]
    proposal = _planner(server.base_url, max_retries=1).propose("Find a mug.", NO_MAP)
    assert proposal.failure is None and proposal.goals == (GoalQuery("mug"),)


def test_a_body_that_is_not_a_chat_reply_is_a_failure(server):
    server.replies = [("raw", b"<html>not json</html>")]
    proposal = _planner(server.base_url).propose("Find a mug.", NO_MAP)
    assert proposal.failure == "chat server failed after 1 attempt(s): reply is not JSON (JSONDecodeError)"


def test_empty_instruction_makes_no_request(server):
    proposal = _planner(server.base_url).propose("  ", NO_MAP)
    assert proposal.failure == "empty instruction" and server.requests == []
    with pytest.raises(TypeError, match="instruction: expected a str, got bytes"):
        _planner(server.base_url).propose(b"Find a mug.", NO_MAP)
    with pytest.raises(TypeError, match="context: expected a PlannerContext, got NoneType"):
        _planner(server.base_url).propose("Find a mug.", None)


def test_check_server_lists_the_models(server):
    assert _planner(server.base_url, api_key="sk-1").check_server() == ("test-model",)
    path, headers = server.gets[0]
    assert path == "/v1/models" and headers["Authorization"] == "Bearer sk-1"


@pytest.mark.parametrize("status, message", [(401, r"refused no api_key \(none was set\): HTTP 401"),
                                             (403, r"refused no api_key \(none was set\): HTTP 403"),
                                             (404, r"answered HTTP 404 \(is base_url the API root")])
def test_check_server_refused(server, status, message):
    server.models = (status, {"error": "nope"})
    with pytest.raises(AgentError, match=rf"chat server at {server.base_url}/models {message}"):
        _planner(server.base_url).check_server()


def test_check_server_not_a_model_list(server):
    server.models = (200, {"status": "ok"})
    with pytest.raises(AgentError, match=r"answered something other than a model list"):
        _planner(server.base_url).check_server()


def test_check_server_unreachable():
    with socket.socket() as s:  # bind a port, then close it: nothing listens there
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(AgentError, match=rf"chat server at http://127.0.0.1:{port}/v1/models cannot be reached: server unreachable"):
        _planner(f"http://127.0.0.1:{port}/v1").check_server()


def test_make_planner_builds_the_chat_backend_without_a_request():
    planner = make_planner("chat", base_url="http://127.0.0.1:9/v1", model="qwen2.5-7b-instruct")
    assert isinstance(planner, ChatPlanner) and planner.name == "chat"
    assert planner.config.url == "http://127.0.0.1:9/v1/chat/completions"


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"base_url": "127.0.0.1:8080/v1"}, r"base_url: expected an http:// or https:// URL, got '127.0.0.1:8080/v1'"),
        ({"base_url": "ftp://host/v1"}, r"base_url: expected an http:// or https:// URL, got 'ftp://host/v1'"),
        ({"base_url": "http:///v1"}, r"base_url: expected a host \(http://HOST\[:PORT\]/...\), got 'http:///v1'"),
        ({"api_key": "sk-1 2"}, r"api_key: .* got a str of 6 characters with whitespace at index 4 \(the key is not shown\)"),
        ({"api_key": "sk-1\r\nX-Evil: 1"}, r"api_key: .* with whitespace at index 4"),
        ({"api_key": "sk-\x001"}, r"api_key: .* with a control character at index 3"),
        ({"api_key": ""}, r"api_key: .* got an empty str"),
        ({"max_rounds": -1}, r"max_rounds: expected an int >= 0, got -1"),
        ({"max_rounds": True}, r"max_rounds: expected an int >= 0, got True"),
        ({"json_mode": "yes"}, r"json_mode: expected a bool, got 'yes'"),
        ({"timeout_s": 0}, r"timeout_s: expected a number > 0, got 0"),
        ({"temperature": float("nan")}, r"temperature: expected a finite number >= 0"),
        ({"model": ""}, r"model: expected a non-empty str, got ''"),
    ],
)
def test_config_refuses_bad_settings(kwargs, message):
    kwargs.setdefault("base_url", "http://127.0.0.1:8080/v1")
    with pytest.raises(AgentError, match=message):
        ChatPlannerConfig(**kwargs)
    with pytest.raises(AgentError, match=message):
        make_planner("chat", **kwargs)


def test_planner_refuses_a_non_config():
    with pytest.raises(TypeError, match=r"config: expected a ChatPlannerConfig, got dict"):
        ChatPlanner({"base_url": "http://127.0.0.1:8080/v1"})


def test_prompt_lists_the_eight_comparators_and_the_reply_format():
    for i, name in enumerate(COMPARATOR_NAMES, 1):
        assert f"\n{i}. {name}(a, b): " in PLANNER_PROMPT
    assert '{"questions": [{"function": "...", "a": "...", "b": "..."}], "goals": [{"phrase": "...", "room": null}], ' \
           '"reasoning": "..."}' in PLANNER_PROMPT
    example = [line[len("Reply: "):] for line in PLANNER_PROMPT.splitlines() if line.startswith("Reply: ")]
    assert [sorted(json.loads(e)) for e in example] == [["goals", "questions", "reasoning"]] * 2
