"""One error hierarchy: every error class of the project derives from ``ConceptFusionError``.

Every module of the project's packages is imported and each ``Exception`` subclass it defines
(``cls.__module__`` is the module) is checked: it derives from
:class:`conceptfusion.errors.ConceptFusionError` and, apart from that base itself, also from the
built-in class a caller would catch (``ValueError``, ``TypeError``, ``ImportError``, ...).
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from pathlib import Path

import pytest

from conceptfusion.errors import ConceptFusionError

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("conceptfusion", "sim_envs", "agents", "planners", "harness", "tower_training", "scenes")

EXEMPT = {
    "agents.llm_http.AttemptError": "retry signal of the chat-completions HTTP client; always caught by its "
    "callers (agents.spatial.llm, agents.instruct.chat), never leaves them",
    "harness.runner.jobs.JobTimeout": "a control-flow signal like KeyboardInterrupt (a BaseException, "
    "so a job's `except Exception` cannot swallow it); the serial backend catches it and records "
    "`timeout`, it never reaches a caller",
    "harness.commands.RunTerminated": "SIGTERM during cfharness run, raised as a KeyboardInterrupt so that every job "
    "lets it through; cmd_run catches it and exits 143, it never reaches a caller",
}
"""Error classes that need not join the hierarchy -> why."""


def _module_names() -> list[str]:
    names = []
    for pkg in PACKAGES:
        names.append(pkg)
        names.extend(info.name for info in pkgutil.walk_packages([str(ROOT / pkg)], pkg + "."))
    return sorted(names)


MODULES = _module_names()


def _import(name: str):
    try:
        return importlib.import_module(name)
    except ImportError as exc:  # an optional third-party package; the project's own must import
        if exc.name is None or exc.name.split(".")[0] in PACKAGES:
            raise
        pytest.skip(f"{name} needs the optional package {exc.name!r}")


def _error_classes(module) -> list[type[BaseException]]:
    return [c for _, c in inspect.getmembers(module, inspect.isclass)
            if issubclass(c, BaseException) and c.__module__ == module.__name__]


def test_every_package_module_is_walked():
    assert len(MODULES) > 50
    assert {"conceptfusion.errors", "planners.errors", "sim_envs.scenes.episodes", "harness.runner.results"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_error_classes_derive_from_the_project_base(name):
    module = _import(name)
    for cls in _error_classes(module):
        qualname = f"{name}.{cls.__name__}"
        if qualname in EXEMPT:
            continue
        assert issubclass(cls, ConceptFusionError), f"{qualname} does not derive from ConceptFusionError"
        if cls is not ConceptFusionError:
            builtin = [b for b in cls.__mro__ if b.__module__ == "builtins" and b not in (Exception, BaseException, object)]
            assert builtin, f"{qualname} derives from no built-in error class a caller would catch"


def test_the_known_error_classes_join_the_hierarchy():
    from conceptfusion import errors
    from harness.runner.backends import RayUnavailableError
    from harness.runner.results import ResultsFormatError
    from planners.errors import PlannerError, PlannerTypeError, UnknownPlannerError
    from sim_envs.scenes.episodes import EpisodeFormatError

    assert PlannerError is errors.PlannerError
    assert issubclass(PlannerTypeError, TypeError)
    assert issubclass(UnknownPlannerError, errors.UnknownNameError)
    assert issubclass(EpisodeFormatError, errors.SimError) and issubclass(EpisodeFormatError, ValueError)
    assert issubclass(ResultsFormatError, errors.HarnessError) and issubclass(ResultsFormatError, ValueError)
    assert issubclass(RayUnavailableError, ConceptFusionError) and issubclass(RayUnavailableError, RuntimeError)
    assert issubclass(errors.UnknownKeyError, KeyError) and issubclass(errors.UnknownKeyError, errors.UnknownNameError)
    assert str(errors.UnknownKeyError("unknown asset 'x'")) == "unknown asset 'x'"


def test_checkpoint_error_is_defined_once():
    import conceptfusion.perception.masks.sam as sam
    from conceptfusion.errors import CheckpointError

    assert sam.CheckpointError is CheckpointError
    defined = [n for n in MODULES if "CheckpointError" in vars(_import(n)) and _import(n).CheckpointError.__module__ == n]
    assert defined == ["conceptfusion.errors"]
