"""report.html in headless Chromium, opened from disk: tables sort by a click on their header, the
episode table's filter hides rows, and replay links lead to the files beside the run."""

from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest
try:
    from selenium.webdriver.common.by import By
except ImportError:  # the chromium fixture fails each test with the command that installs it
    By = None

from harness.report.html import write_reports
from harness.report.paths import replay_stem
from harness.runner.results import append_record, make_record

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("report-page")
    rng = np.random.default_rng(3)
    for i in range(15):
        for agent, rate in (("map-navigator", 0.8), ("frame-searcher", 0.5), ("random-walker", 0.1)):
            win = bool(rng.random() < rate)
            rec = make_record(run_id="r", suite="search", task="object_search", agent=agent, encoder="test",
                              episode_id=f"search-{i:04d}", seed=0, status="ok",
                              metrics={"success": win, "spl": 0.9 * win * rng.random()}, timings={"wall_s": 1.0 + i},
                              extras={"uses_map": agent == "map-navigator"})
            append_record(root / "run" / "results.jsonl", rec)
            if not win:
                (root / "run" / "replays").mkdir(exist_ok=True)
                (root / "run" / "replays" / f"{replay_stem(rec)}.gif").write_bytes(b"GIF89a")
    _, page = write_reports([root / "run"], root / "run" / "report", title="Browser test report")
    return page


@pytest.fixture(scope="module")
def page(chromium, report):
    chromium.get(report.as_uri())
    assert chromium.title == "Browser test report"
    return chromium


def _column(driver, table_id, index):
    return driver.execute_script(
        "return Array.from(document.getElementById(arguments[0]).tBodies[0].rows)"
        ".filter(r => !r.hidden).map(r => r.cells[arguments[1]].textContent)", table_id, index)


def test_clicking_a_header_sorts_the_table(page, artifacts):
    table = page.find_element(By.ID, "suite-search")
    heads = [th.get_attribute("textContent") for th in table.find_elements(By.TAG_NAME, "th")]
    assert "success" in heads, heads
    col = heads.index("success")
    header = table.find_elements(By.TAG_NAME, "th")[col]
    assert _column(page, "suite-search", 0)[0] == "map-navigator"  # the best agent first, before any click
    header.click()
    up = [float(v.split()[0]) for v in _column(page, "suite-search", col)]
    assert up == sorted(up) and header.get_attribute("aria-sort") == "ascending"
    header.click()
    down = [float(v.split()[0]) for v in _column(page, "suite-search", col)]
    assert down == sorted(down, reverse=True) and header.get_attribute("aria-sort") == "descending"
    assert _column(page, "suite-search", 0)[0] == "map-navigator"  # the best agent first
    page.save_screenshot(str(artifacts / "report_sorted.png"))


def test_episode_table_sorts_by_numbers_and_filters(page):
    table = page.find_element(By.ID, "episodes-search")
    heads = [th.get_attribute("textContent") for th in table.find_elements(By.TAG_NAME, "th")]
    assert _column(page, "episodes-search", heads.index("outcome"))[0] == "miss"  # failures first
    page.execute_script("arguments[0].open = true", table.find_element(By.XPATH, "ancestor::details"))
    table.find_elements(By.TAG_NAME, "th")[heads.index("s")].click()
    walls = [float(v) for v in _column(page, "episodes-search", heads.index("s"))]
    assert walls == sorted(walls) and walls[0] < walls[-1]  # numbers, not text: 10.0 after 9.0
    box = page.find_element(By.CSS_SELECTOR, "input.filter[data-table='episodes-search']")
    box.send_keys("random-walker search-0007")
    agents = _column(page, "episodes-search", heads.index("agent"))
    episodes = _column(page, "episodes-search", heads.index("episode"))
    assert agents == ["random-walker"] and episodes == ["search-0007"]
    box.clear()
    box.send_keys(" ")
    assert len(_column(page, "episodes-search", 0)) == 45


def test_replay_links_open_files_beside_the_run(page, report):
    links = page.find_elements(By.CSS_SELECTOR, "#episodes-search a")
    hrefs = [a.get_attribute("href") for a in links]
    assert hrefs and all(h.startswith("file://") and h.endswith(".gif") for h in hrefs)
    for h in hrefs:
        path = Path(unquote(urlsplit(h).path))
        assert path.is_file() and path.parent == report.parent.parent / "replays"
    assert len(hrefs) == len(list((report.parent.parent / "replays").glob("*.gif")))
