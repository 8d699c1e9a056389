"""``cfharness report RUN --bundle``: one folder (and a zip) holding the report, its figures, the
failure pages and every video they link, whose links all stay inside it wherever it is moved;
maps only with ``--bundle-maps``."""

import json
import shutil
import zipfile
from pathlib import Path
from urllib.parse import unquote

import pytest

from harness.cli import main
from harness.report.bundle import BUNDLE_MARKER, links_outside, page_links, write_bundle
from harness.report.paths import replay_stem
from harness.runner.results import append_record, make_record, write_run_config


def _run(folder: Path) -> list[dict]:
    """A small run: search episodes of two agents, the failures with a video, the map agent's
    failures with a map too."""
    write_run_config(folder, {"run_id": "A", "record": "failures"})
    recs = []
    for i in range(4):
        for agent, enc in (("map-navigator", "test"), ("random-walker", "none")):
            win = agent == "map-navigator" and i % 2 == 0
            rec = make_record(run_id="A", suite="search", task="object_search", agent=agent, encoder=enc,
                              episode_id=f"search-{i:04d}", seed=0, status="ok", category=("mug", "cup")[i % 2],
                              metrics={"success": win, "spl": 0.5 * win, "distance_to_goal": 0.5 if win else 3.0},
                              timings={"wall_s": 1.0}, extras={"goal": f"goal {i}", "path_xy": [[0, 0], [1, 1]]})
            append_record(folder / "results.jsonl", rec)
            recs.append(rec)
            if not win:
                (folder / "replays").mkdir(parents=True, exist_ok=True)
                (folder / "replays" / f"{replay_stem(rec)}.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(i))
                if agent == "map-navigator":
                    (folder / "replays" / f"{replay_stem(rec)}.map.npz").write_bytes(b"PK\x03\x04")
    return recs


def _check_inside(folder: Path) -> int:
    """Assert every href/src of every page resolves to a file inside ``folder``; returns how many
    file links there are."""
    n = 0
    root = folder.resolve()
    pages = sorted(folder.rglob("*.html"))
    assert pages
    for page in pages:
        for target in page_links(page.read_text(encoding="utf-8")):
            if target.startswith(("#", "data:")):
                continue
            assert "://" not in target and not target.startswith("/"), f"{page.name}: {target}"
            resolved = (page.parent / unquote(target.split("#")[0])).resolve()
            assert resolved.is_relative_to(root) and resolved.is_file(), f"{page.name}: {target}"
            n += 1
    return n


@pytest.fixture(scope="module")
def bundled(tmp_path_factory):
    root = tmp_path_factory.mktemp("bundle")
    recs = _run(root / "run")
    done = write_bundle([root / "run"], root / "out" / "b.zip")
    return root, recs, done


def test_bundle_holds_the_report_pages_and_every_linked_video(bundled):
    root, recs, done = bundled
    folder = done.folder
    assert folder == root / "out" / "b" and done.zip_path == root / "out" / "b.zip"
    names = {p.as_posix() for p in done.files}
    assert {"report.html", "report.md", "failures-search.html", BUNDLE_MARKER} <= names
    videos = sorted(p.name for p in (root / "run" / "replays").glob("*.mp4"))
    assert sorted(Path(n).name for n in names if n.endswith(".mp4")) == videos and done.videos == len(videos) == 6
    assert not any(n.endswith(".map.npz") for n in names) and done.maps == 0  # maps left out by default
    marker = json.loads((folder / BUNDLE_MARKER).read_text())
    assert marker["runs"] == [str((root / "run").resolve())] and marker["maps"] is False


def test_bundle_links_resolve_inside_it_after_a_move_and_an_unzip(bundled, tmp_path):
    root, _, done = bundled
    moved = tmp_path / "elsewhere" / "mailed"
    shutil.copytree(done.folder, moved)
    n = _check_inside(moved)
    assert n >= 6 + 2  # the videos of the failure page and of the episode table, and the back links
    assert links_outside(moved) == []
    with zipfile.ZipFile(done.zip_path) as zf:
        zf.extractall(tmp_path / "unzipped")
    assert _check_inside(tmp_path / "unzipped" / "b") == n
    text = (moved / "report.html").read_text()
    assert "../" not in "".join(page_links(text))


def test_maps_left_out_show_the_command_from_the_run_folder(bundled):
    root, recs, done = bundled
    page = (done.folder / "failures-search.html").read_text()
    stem = replay_stem(next(r for r in recs if r["agent"] == "map-navigator" and not r["metrics"]["success"]))
    assert f"cfharness view replays/{stem}.map.npz --encoder test" in page
    assert f"run it in the run folder {root / 'run'}" in page and "--bundle-maps copies them" in page


def test_bundle_maps_copies_them_and_links_the_copies(tmp_path):
    _run(tmp_path / "run")
    done = write_bundle([tmp_path / "run"], tmp_path / "bundle", maps=True)
    assert done.zip_path is None and done.maps == 2
    assert len(list((done.folder / "maps").glob("*.map.npz"))) == 2
    page = (done.folder / "failures-search.html").read_text()
    assert "cfharness view maps/" in page and "run it in this report&#x27;s folder" in page
    assert links_outside(done.folder) == []


def test_links_outside_finds_a_link_that_leaves(tmp_path):
    (tmp_path / "a.html").write_text('<a href="../x.mp4">x</a><img src="data:image/png;base64,AA"><a href="#top">t</a>'
                                     '<video src="https://example.org/v.mp4"></video>')
    bad = links_outside(tmp_path)
    assert len(bad) == 2 and "../x.mp4" in bad[0] and "not a relative link" in bad[1]


def test_bundle_refuses_a_folder_that_is_not_a_bundle(tmp_path):
    _run(tmp_path / "run")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(ValueError, match="neither empty nor a previous bundle"):
        write_bundle([tmp_path / "run"], tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"
    first = write_bundle([tmp_path / "run"], tmp_path / "b")
    again = write_bundle([tmp_path / "run"], tmp_path / "b")  # a previous bundle is replaced
    assert again.files == first.files


def test_cli_bundle(tmp_path, capsys):
    _run(tmp_path / "run")
    assert main(["report", str(tmp_path / "run"), "--bundle"]) == 0
    assert "report bundle:" in capsys.readouterr().out and (tmp_path / "run" / "report-bundle" / "report.html").is_file()
    assert main(["report", str(tmp_path / "run"), "--bundle", str(tmp_path / "x.zip")]) == 0
    assert zipfile.is_zipfile(tmp_path / "x.zip")
    assert main(["report", str(tmp_path / "run"), "--bundle", str(tmp_path / "y"), "--out", str(tmp_path / "z")]) == 2
    assert "--out and --bundle" in capsys.readouterr().err
