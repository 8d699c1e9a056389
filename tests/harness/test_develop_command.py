"""``cfharness develop``: the development tools behind one command, each still a ``python -m`` module."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest

from harness.cli import main
from harness.develop_command import TOOLS


def _main_params(module: str) -> list[str] | None:
    """The parameters of ``module``'s top-level ``main``, read from its source (nothing imported:
    the tower's training modules import torch); None without one."""
    tree = ast.parse(Path(importlib.util.find_spec(module).origin).read_text())
    fn = next((n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "main"), None)
    return None if fn is None else [a.arg for a in fn.args.args]


def test_without_a_tool_it_lists_every_tool_on_one_line(capsys):
    assert main(["develop"]) == 0
    lines = capsys.readouterr().out.splitlines()[1:]
    assert [line.split()[0] for line in lines] == list(TOOLS)
    for line, (name, tool) in zip(lines, TOOLS.items()):
        assert tool.summary in line and line.endswith(f"(python -m {tool.module})")


@pytest.mark.parametrize("name", sorted(TOOLS))
def test_every_tool_is_a_module_with_main_argv(name):
    assert _main_params(TOOLS[name].module) == ["argv"]


def test_a_tools_help_comes_through_develop(capsys):
    assert main(["develop", "episodes", "--help"]) == 0
    out = capsys.readouterr().out
    assert "--suite" in out and "--episodes" in out and "--env-option" in out


def test_the_arguments_reach_the_tool(tmp_path, capsys):
    assert main(["develop", "episodes", "--suite", "rearrange", "--out", str(tmp_path / "unused")]) == 2
    assert "--suite: expected a suite with development episodes" in capsys.readouterr().err


def test_an_unknown_tool_is_refused_naming_the_nearest(capsys):
    assert main(["develop", "room-flor"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cfharness develop: unknown tool 'room-flor'; did you mean 'room-floor'")
    assert "(tools: episodes, query-open" in err
