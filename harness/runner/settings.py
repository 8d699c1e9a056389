"""Checking run settings before anything runs: :func:`validate_run_config` for a
:class:`~harness.runner.run.RunConfig`, and the values the map suites' options accept
(:data:`MAP_SUITE_OPTIONS`).

Every problem is a :class:`~conceptfusion.errors.HarnessError` (a ``ValueError``) whose message
starts with the command-line flag of the setting and says what was expected, what arrived and,
for names, the nearest valid ones: ``--limit: expected an integer >= 1 (episodes or scenes per
suite), got -148``; ``--agent-option bogus: no agent or suite of this run takes it (options of
this run: ...)``.
"""

from __future__ import annotations

import inspect
import math
import typing
from typing import Any, Callable

from agents.registry import AGENTS, agent_names, resolve_agent
from agents.spec import Option, check_option, missing_agent_methods
from conceptfusion.errors import HarnessError
from conceptfusion.names import did_you_mean, unknown_name_error
from conceptfusion.perception.featurizer import PerceptionSpec
from conceptfusion.perception.registry import check_encoder_files
from harness.maps.spatial import DEFAULT_PARSER, SUITE_PARSERS
from harness.maps.suites import MAP_SUITES
from harness.replay.record import check_record_mode
from harness.runner.backends import BACKENDS, memory_limit_refusal, parse_ray_address
from harness.runner.jobs import import_plugins
from harness.runner.suites import EPISODES_PREFIX, SUITES, Suite, get_suite

__all__ = ["validate_run_config", "MAP_SUITE_OPTIONS", "check_agent", "check_agent_factory", "accepts_keyword"]


MAP_SUITE_OPTIONS: dict[str, Option] = {
    "frames": Option.at_least(int, 12, 1),
    "width": Option.at_least(int, 160, 1),
    "height": Option.at_least(int, 120, 1),
    "proposer": Option(str, "rgbd", lambda v: bool(PerceptionSpec.parse("color", proposer=v)), "a mask proposer name"),
    "parser": Option(str, DEFAULT_PARSER, lambda v: v in SUITE_PARSERS, f"a spatial-question parser: {' or '.join(SUITE_PARSERS)}"),
    "assume_present": Option(bool, True),
    "name_only_fallback": Option(bool, True),
}
"""The values the map suites' options (``agent_kwargs`` keys they read, see
:mod:`harness.maps.suites`) accept."""


def _names(value: Any, flag: str, *, allow_none: bool = False) -> tuple[str, ...] | None:
    if value is None and allow_none:
        return None
    if isinstance(value, str):
        value = (value,)
    try:
        names = tuple(value)
    except TypeError:
        raise HarnessError(f"{flag}: expected a sequence of names, got {type(value).__name__} {value!r}") from None
    for n in names:
        if not isinstance(n, str) or not n.strip():
            raise HarnessError(f"{flag}: expected non-empty names, got {n!r}")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise HarnessError(f"{flag}: each name once, got {', '.join(map(repr, twice))} more than once")
    return names


def _int(value: Any, flag: str, low: int, what: str, *, allow_none: bool = False) -> int | None:
    if value is None and allow_none:
        return None
    expected = f"expected an integer >= {low} ({what})"
    if isinstance(value, str):
        try:
            out = int(value.strip())
        except ValueError:
            raise HarnessError(f"{flag}: {expected}, got {value!r}") from None
    elif isinstance(value, bool) or not isinstance(value, (int, float)) or (isinstance(value, float) and not value.is_integer()):
        raise HarnessError(f"{flag}: {expected}, got {type(value).__name__} {value!r}")
    else:
        out = int(value)
    if out < low:
        raise HarnessError(f"{flag}: {expected}, got {value!r}")
    return out


def _seconds(value: Any, flag: str) -> float | None:
    if value is None:
        return None
    expected = "expected a number of seconds > 0"
    try:
        out = float(value.strip() if isinstance(value, str) else value)
    except (TypeError, ValueError):
        out = None
    if isinstance(value, bool) or out is None or not math.isfinite(out) or out <= 0:
        raise HarnessError(f"{flag}: {expected}, got {value!r}")
    return out


def accepts_keyword(factory: Callable, key: str, *, unknown: bool = True) -> bool:
    """Whether a user agent's factory takes keyword ``key`` (``unknown`` when its signature is unknown)."""
    try:
        params = inspect.signature(factory).parameters
    except (TypeError, ValueError):  # a callable without a signature (some builtins)
        return unknown
    return key in params or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())


def _keywords(factory: Callable) -> list[str]:
    """The keyword parameters a user agent's factory names (none when its signature is unknown)."""
    try:
        params = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):
        return []
    return [p.name for p in params if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)]


def _describe(obj: Any) -> str:
    name = f"{getattr(obj, '__module__', None) or '?'}.{getattr(obj, '__qualname__', None) or type(obj).__name__}"
    if inspect.isclass(obj):
        return f"class {name}"
    if inspect.isbuiltin(obj):
        return f"built-in function {name}"
    return f"{type(obj).__name__} {obj!r}"[:120] if not callable(obj) else f"{type(obj).__name__} {name}"


def check_agent_factory(agent: str, factory: Any, agent_kwargs: dict) -> None:
    """Check, before any episode, that a user agent's import path names something that builds an
    agent with the keywords the run passes (the ``agent_kwargs`` it accepts, and ``encoder`` when
    it takes one), without building it:

    - a class must have callable ``reset`` and ``act`` (on the class: ``privileged`` may be set
      by ``__init__``, and is checked when the agent is built) and a constructor that takes those
      keywords and needs no others;
    - another Python callable (a factory function) must take those keywords and need no others,
      and, when its return annotation is a class, that class must have ``reset`` and ``act``;
      what an unannotated factory returns is checked when the first episode builds the agent
      (a ``failed`` record naming what is missing);
    - anything else (a built-in function such as ``os:getcwd``, a constant) is refused.

    Raises:
        HarnessError: naming the import path, what was expected and what it names.
    """
    expected = "an agent class with reset() and act(), or a function that builds one"
    if not callable(factory) or inspect.isbuiltin(factory) or (
            not inspect.isclass(factory) and not inspect.isroutine(factory) and type(factory).__module__ == "builtins"):
        raise HarnessError(f"--agent {agent}: expected {expected}, got {_describe(factory)}")
    made = factory if inspect.isclass(factory) else None
    if made is None:
        try:
            made = typing.get_type_hints(factory).get("return")
        except Exception:  # unresolvable annotations: nothing to learn from them
            made = None
    if inspect.isclass(made):
        missing = missing_agent_methods(made)
        if missing:
            where = "" if made is factory else f", whose return annotation says it builds {_describe(made)}"
            raise HarnessError(f"--agent {agent}: expected {expected}, got {_describe(factory)}{where} without "
                               f"{' and '.join(m + '()' for m in missing)}")
    try:
        signature = inspect.signature(factory)
    except (TypeError, ValueError):  # no signature to check
        return
    keywords = sorted({k for k in agent_kwargs if accepts_keyword(factory, k)}
                      | ({"encoder"} if accepts_keyword(factory, "encoder", unknown=False) else set()))
    try:
        signature.bind(**{k: None for k in keywords})
    except TypeError as exc:
        raise HarnessError(f"--agent {agent}: expected {expected} from the keywords the run passes "
                           f"({', '.join(keywords) or 'none'}), but {_describe(factory)}{signature} cannot be called "
                           f"so: {exc}") from None


def _resolve(agent: str) -> Callable:
    try:
        return resolve_agent(agent)
    except ValueError as exc:
        raise HarnessError(f"--agent: {exc}") from exc


def _check_options(config, suites: list[Suite]) -> None:
    if not isinstance(config.agent_kwargs, dict):
        raise HarnessError(f"--agent-option: expected a dict of KEY=VALUE options, got {type(config.agent_kwargs).__name__}")
    takers: dict[str, list[str]] = {}  # option -> who takes it, for the messages
    checks: dict[str, list[tuple[str, Callable[[Any], Any]]]] = {}
    for suite in suites:
        if suite.kind == "maps":
            for key in MAP_SUITES[suite.name].options:
                takers.setdefault(key, []).append(f"suite {suite.name!r}")
                checks.setdefault(key, []).append((f"suite {suite.name!r}", lambda v, k=key: MAP_SUITE_OPTIONS[k].convert(
                    f"suite option {k!r}", v)))
            continue
        for agent in config.agents or suite.agents:
            spec = AGENTS.get(agent)
            if spec is not None:
                for key in spec.kwargs:
                    takers.setdefault(key, []).append(f"agent {agent!r}")
                    checks.setdefault(key, []).append((agent, lambda v, s=spec, k=key: check_option(s, k, v)))
            else:
                factory = _resolve(agent)
                for key in [*_keywords(factory), *config.agent_kwargs]:
                    if accepts_keyword(factory, key):
                        takers.setdefault(key, []).append(f"agent {agent!r}")
    for key, value in config.agent_kwargs.items():
        if not isinstance(key, str) or not key:
            raise HarnessError(f"--agent-option: expected KEY=VALUE with a non-empty KEY, got key {key!r}")
        if key == "encoder":
            raise HarnessError(f"--agent-option encoder={value}: the encoder is a run setting; give it with --encoder")
        if key not in takers:
            known = sorted(k for k in takers if k != "encoder")
            raise HarnessError(
                f"--agent-option {key}: no agent or suite of this run takes it{did_you_mean(key, known, n=2, cutoff=0.6)} "
                f"(options of this run: {', '.join(known) or 'none'})")
        for _, check in checks.get(key, ()):
            try:
                check(value)
            except (ValueError, TypeError) as exc:
                raise HarnessError(f"--agent-option {key}={value}: {exc}") from exc
    _check_planner_server(config.agent_kwargs)


def _check_planner_server(kwargs: dict) -> None:
    """With ``--agent-option planner=chat``: the planner is built (its URL and key checked) and its
    server asked once for its models, so a bad URL, a refused key or a server that is not there
    stops the run before any episode."""
    if kwargs.get("planner") != "chat":
        return
    from agents.builtin import planner_options
    from agents.instruct.planner import make_planner

    try:
        make_planner("chat", **planner_options("chat", str(kwargs.get("planner_url", "")),
                                               str(kwargs.get("planner_model", "")))).check_server()
    except (ValueError, TypeError) as exc:
        raise HarnessError(f"--agent-option planner=chat: {exc}") from exc


def validate_run_config(config: Any) -> None:
    """Check every setting of ``config`` (a :class:`~harness.runner.run.RunConfig`, which calls
    this on construction) and normalise it in place (numbers given as strings
    become numbers, name lists tuples, the encoder its canonical string); imports the plugins
    and resolves user agents. Loads no model and runs nothing.

    Raises:
        HarnessError: (a ``ValueError``) the first bad setting; the message starts with its
            command-line flag and says what was expected, what arrived and the nearest valid names.
    """
    def put(name: str, value: Any) -> None:
        object.__setattr__(config, name, value)

    put("plugins", _names(config.plugins, "--import"))
    try:
        import_plugins(config.plugins)
    except ValueError as exc:
        raise HarnessError(str(exc)) from exc
    put("suites", _names(config.suites, "--suite"))
    if not config.suites:
        raise HarnessError(f"--suite: expected at least one suite (suites: {', '.join(SUITES)})")
    suites = []
    for name in config.suites:
        try:
            suites.append(get_suite(name))
        except ValueError as exc:  # a user's episode file says --episodes itself
            raise HarnessError(str(exc) if name.startswith(EPISODES_PREFIX) else f"--suite: {exc}") from exc
    put("agents", _names(config.agents, "--agent", allow_none=True))
    episode_suites = [s for s in suites if s.kind == "episodes"]
    if config.agents:
        if not episode_suites:
            raise HarnessError(f"--agent: the map suites ({', '.join(config.suites)}) run no agents; --agent is for the "
                               f"episode suites ({', '.join(n for n, s in SUITES.items() if s.kind == 'episodes')})")
        for suite in episode_suites:
            for agent in config.agents:
                try:
                    check_agent(agent, suite)
                except ValueError as exc:
                    raise HarnessError(f"--agent: {exc}") from exc
        for agent in config.agents:
            if agent not in AGENTS:
                check_agent_factory(agent, _resolve(agent), config.agent_kwargs)
    try:
        if config.encoder is not None:
            spec = PerceptionSpec.parse(config.encoder)
            if not spec.privileged:  # the oracles read the simulator: no files
                check_encoder_files(spec.encoder)
            put("encoder", str(spec))
    except (ValueError, TypeError, OSError) as exc:
        raise HarnessError(f"--encoder: {exc}") from exc
    put("limit", _int(config.limit, "--limit", 1, "episodes or scenes per suite", allow_none=True))
    put("seed", _int(config.seed, "--seed", 0, "the episode seed"))
    put("seeds", _int(config.seeds, "--seeds", 1, "seeds per episode"))
    if config.backend not in BACKENDS:
        raise HarnessError(f"--backend: expected one of {', '.join(BACKENDS)}, got {config.backend!r}"
                           + did_you_mean(config.backend, BACKENDS, n=1, cutoff=0.5))
    put("workers", _int(config.workers, "--workers", 1, "worker processes", allow_none=True))
    if config.address is not None:
        if config.backend != "ray":
            raise HarnessError(f"--address: only for --backend ray (a Ray cluster), got --backend {config.backend} "
                               f"with --address {config.address!r}")
        if not isinstance(config.address, str) or not config.address.strip():
            raise HarnessError(f"--address: expected 'auto', 'HOST:PORT' or 'ray://HOST:PORT', got {config.address!r}")
        parse_ray_address(config.address)
    put("timeout_s", _seconds(config.timeout_s, "--timeout"))
    put("memory_limit_mb", _int(config.memory_limit_mb, "--memory-limit-mb", 1, "MiB of memory per episode worker",
                                allow_none=True))
    refusal = memory_limit_refusal(config.backend) if config.memory_limit_mb is not None else None
    if refusal:
        raise HarnessError(refusal)
    check_record_mode(config.record, "--record")
    _check_options(config, suites)


def check_agent(agent: str, suite: Suite) -> None:
    """``ValueError`` unless ``agent`` (a registered name or ``'module:Class'``) fits episode suite ``suite``."""
    if agent in AGENTS:
        if AGENTS[agent].task not in (suite.task, "any"):
            raise ValueError(f"agent {agent!r} solves {AGENTS[agent].task}, not suite {suite.name!r} ({suite.task}); "
                             f"agents for it: {', '.join(agent_names(suite.task))}")
        return
    if ":" not in agent:
        raise unknown_name_error("agent", agent, AGENTS,
                                 listing=f"for suite {suite.name!r}: {', '.join(agent_names(suite.task))}; or 'module:Class'")
