"""report.html answers the question on its first screen: at a 1400x900 page every suite's card lies
within the first 900 px and names the question, the best agent, its baseline and the difference;
a query-open-like table (many column groups) fits its box until a group is shown."""

import numpy as np
import pytest
try:
    from selenium.webdriver.common.by import By
except ImportError:  # the chromium fixture fails each test with the command that installs it
    By = None

from harness.report.cards import headline_cards
from harness.report.html import write_reports
from harness.runner.results import append_record, make_record

pytestmark = pytest.mark.browser

WIDTH, HEIGHT = 1400, 900
_KINDS = ("name", "synonym", "parent", "colour", "material", "function", "seen", "validation", "held_out_instance",
          "held_out_category")


def _records():
    """Two episode suites with matched twins (rearrange-v2, search-v2), spatial-v2 with its declared
    baseline and query-open with its 35 metrics in 13 groups."""
    rng = np.random.default_rng(7)
    recs = []

    def add(suite, agent, i, metrics, encoder="embedded-v2", **extras):
        recs.append(make_record(run_id="r", suite=suite, task="t", agent=agent, encoder=encoder, episode_id=f"{suite}-{i:03d}",
                                seed=0, status="ok", metrics=metrics, timings={"wall_s": 1.0}, extras=extras))

    for suite, agents in (("rearrange-v2", ("map-pusher", "twin-pusher", "random-pusher")),
                          ("search-v2", ("map-navigator", "twin-navigator", "random-walker"))):
        mapper, twin, rand = agents
        for i in range(24):
            add(suite, mapper, i, {"success": bool(rng.random() < 0.75), "steps": 40 + i}, uses_map=True)
            add(suite, twin, i, {"success": bool(rng.random() < 0.4), "steps": 50 + i}, uses_map=False, twin_of=mapper)
            add(suite, rand, i, {"success": bool(rng.random() < 0.05), "steps": 90}, encoder="none", uses_map=False)
    for i in range(12):
        add("spatial-v2", "map-3d", i, {"accuracy": 0.6 + 0.02 * rng.random(), "acc_howFar": 0.5, "n_howFar": 2.0})
        add("spatial-v2", "frame-2.5d", i, {"accuracy": 0.5 + 0.02 * rng.random(), "acc_howFar": 0.25, "n_howFar": 2.0})
        metrics = {f"{k}_{m}": float(rng.random()) for k in _KINDS for m in ("miou", "acc25", "found_rate")}
        add("query-open", "conceptfusion", i, {**metrics, "absent_fp_rate": 0.1, "n_absent": 3.0, "n_queries": 20.0,
                                                "n_unseen": 4.0, "map_points": 23603.0})
    return recs


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("first-screen")
    recs = _records()
    for r in recs:
        append_record(root / "run" / "results.jsonl", r)
    _, page = write_reports([root / "run"], root / "run" / "report", title="First screen")
    return page, headline_cards(recs).cards


@pytest.fixture
def page(chromium, report):
    """The report at a 1400x900 page area (reset afterwards: the browser serves the whole session)."""
    chromium.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                             {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False})
    try:
        chromium.get(report[0].as_uri())
        assert chromium.execute_script("return [window.innerWidth, window.innerHeight]") == [WIDTH, HEIGHT]
        yield chromium
    finally:
        chromium.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})


def test_every_card_is_on_the_first_screen_and_answers_its_question(page, report, artifacts):
    page.save_screenshot(str(artifacts / "report_first_screen.png"))
    expected = {c.title: c for c in report[1]}
    assert set(expected) == {"rearrange-v2", "search-v2", "spatial-v2", "query-open"}
    assert page.execute_script("return window.scrollY") == 0
    cards = page.find_elements(By.CSS_SELECTOR, "article.card")
    assert [c.get_attribute("data-suite") for c in cards] == ["rearrange-v2", "search-v2", "spatial-v2", "query-open"]
    for card in cards:
        suite = card.get_attribute("data-suite")
        box = page.execute_script("var r = arguments[0].getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]", card)
        assert 0 <= box[0] and 0 <= box[1] and box[2] <= WIDTH and box[3] <= HEIGHT, f"card {suite} at {box}, outside the first screen"
        text = " ".join(card.text.split())
        want = expected[suite]
        assert want.question in text and want.best.split(" (")[0] in text, (suite, text)
        if suite == "query-open":  # no baseline: the figure with its interval
            assert want.figure in text and "against" not in text
        else:
            baseline = {"rearrange-v2": "twin-pusher", "search-v2": "twin-navigator", "spatial-v2": "frame-2.5d"}[suite]
            assert baseline in text and want.difference in text and want.difference.startswith(("+", "-")), (suite, text)
    rearrange = " ".join(cards[0].text.split())
    assert "map-pusher (embedded-v2)" in rearrange and "matched map-free twin" in rearrange and "map helps" in rearrange


def _wrap_widths(driver, table_id):
    return driver.execute_script(
        "var t = document.getElementById(arguments[0]), w = t.parentElement;"
        "return [w.clientWidth, w.scrollWidth, t.getBoundingClientRect().width]", table_id)


def test_wide_table_fits_its_box_until_a_group_is_shown(page, artifacts):
    table = page.find_element(By.ID, "suite-query-open")
    box, scroll, width = _wrap_widths(page, "suite-query-open")
    assert box == 1232 and scroll <= box and width <= box, (box, scroll, width)
    buttons = page.find_elements(By.CSS_SELECTOR, ".groups[data-table='suite-query-open'] button[data-group]")
    shown = [b.text for b in buttons if b.get_attribute("aria-pressed") == "true"]
    hidden = [b for b in buttons if b.get_attribute("aria-pressed") == "false"]
    assert shown[0].startswith("name (3)") and len(hidden) >= 8  # the headline's group first, most start hidden
    group = hidden[-1]
    gid = group.get_attribute("data-group")
    assert all(not th.is_displayed() for th in table.find_elements(By.CSS_SELECTOR, f"th[data-group='{gid}']"))
    group.click()
    assert group.get_attribute("aria-pressed") == "true"
    assert all(th.is_displayed() for th in table.find_elements(By.CSS_SELECTOR, f"th[data-group='{gid}']"))
    _, _, wider = _wrap_widths(page, "suite-query-open")
    assert wider > width
    page.find_element(By.CSS_SELECTOR, ".groups[data-table='suite-query-open'] button.all").click()
    box, scroll, widest = _wrap_widths(page, "suite-query-open")
    assert widest > wider and scroll > box  # every column: wider than the box, it scrolls sideways
    # the agent column stays in view when the table scrolls
    page.execute_script("var t = document.getElementById('suite-query-open'); t.scrollIntoView(); t.parentElement.scrollLeft = 600;")
    left = page.execute_script("var t = document.getElementById('suite-query-open');"
                               "return [t.parentElement.getBoundingClientRect().left, t.tBodies[0].rows[0].cells[0].getBoundingClientRect().left,"
                               " t.tBodies[0].rows[0].cells[1].getBoundingClientRect().left]")
    assert abs(left[1] - left[0]) < 1 and left[2] < left[0]  # pinned; the encoder column scrolled out
    page.save_screenshot(str(artifacts / "report_wide_table.png"))
    page.find_element(By.CSS_SELECTOR, ".groups[data-table='suite-query-open'] button.all").click()  # back to the default
    assert _wrap_widths(page, "suite-query-open")[2] == width


def test_a_grouped_column_sorts_by_its_own_cells(page):
    """In a two-row header a column's cell index is not its position in the body rows: the header
    names its column (``data-col``)."""
    table = page.find_element(By.ID, "suite-rearrange-v2")
    steps = table.find_element(By.XPATH, ".//th[@data-group and normalize-space()='steps']")
    col = int(steps.get_attribute("data-col"))
    assert col != steps.get_property("cellIndex")

    def column():
        return page.execute_script("return Array.from(document.getElementById('suite-rearrange-v2').tBodies[0].rows)"
                                   ".map(r => parseFloat(r.cells[arguments[0]].getAttribute('data-sort')))", col)

    steps.click()
    assert column() == sorted(column()) and steps.get_attribute("aria-sort") == "ascending"
    steps.click()
    assert column() == sorted(column(), reverse=True) and column()[0] == 90  # the random pusher's steps
    agents = page.execute_script("return Array.from(document.getElementById('suite-rearrange-v2').tBodies[0].rows)"
                                 ".map(r => r.cells[0].textContent)")
    assert agents[0] == "random-pusher"
