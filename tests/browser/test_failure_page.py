"""A suite's failure page in headless Chromium, opened from disk: its groups, the copy button that
puts the map viewer's command on the clipboard, and the inline video that loads only when opened."""

import pytest
try:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
except ImportError:  # the chromium fixture fails each test with the command that installs it
    By = Keys = None

from harness.report.failures import failures_file
from harness.report.html import write_reports
from harness.report.paths import replay_stem
from harness.runner.results import append_record, make_record

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def failure_page(tmp_path_factory):
    root = tmp_path_factory.mktemp("failure-page")
    for i, reason in enumerate(("not_found", "not_found", "wrong_object")):
        rec = make_record(run_id="r", suite="search", task="object_search", agent="map-navigator", encoder="test",
                          episode_id=f"search-{i:04d}", seed=0, status="ok", category="mug",
                          metrics={"success": False, "distance_to_goal": 3.0}, timings={"wall_s": 1.0},
                          extras={"goal": f"the mug number {i}", "stop_reason": reason})
        append_record(root / "run" / "results.jsonl", rec)
        (root / "run" / "replays").mkdir(exist_ok=True)
        (root / "run" / "replays" / f"{replay_stem(rec)}.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42")
        (root / "run" / "replays" / f"{replay_stem(rec)}.map.npz").write_bytes(b"PK\x03\x04")
    write_reports([root / "run"], root / "run" / "report", title="Failure page test")
    return root / "run" / "report" / failures_file("search")

def test_failure_page_copy_button_and_video(chromium, failure_page, artifacts, wait_for):
    chromium.get(failure_page.as_uri())
    heads = [h.text for h in chromium.find_elements(By.CSS_SELECTOR, "h2")]
    assert heads[0].startswith("not_found: 2") and heads[1].startswith("wrong_object: 1")
    video = chromium.find_element(By.CSS_SELECTOR, "details.play video")
    assert video.get_attribute("preload") == "none"
    assert chromium.execute_script("return arguments[0].networkState", video) in (0, 1)  # nothing fetched yet
    button = chromium.find_element(By.CSS_SELECTOR, "button.cf-copy")
    command = button.get_attribute("data-copy")
    assert command.startswith("cfharness view ") and command.endswith("--encoder test")
    button.click()
    assert wait_for(chromium, "document.querySelector('button.cf-copy').textContent !== 'copy' && "
                              "document.querySelector('button.cf-copy').textContent", what="the copy button") == "copied"
    box = chromium.execute_script(
        "var t = document.createElement('textarea'); document.body.appendChild(t); t.focus(); return t;")
    box.send_keys(Keys.CONTROL, "v")
    assert box.get_attribute("value") == command
    chromium.save_screenshot(str(artifacts / "failure_page.png"))
