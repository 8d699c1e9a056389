"""The map viewer in headless Chromium: the fused box scene is drawn (WebGL), a text query draws
the found region's box, an absent name says "not found", a click on a point and an uploaded image
are answered, and bad queries show a message."""

import json
import urllib.request

import cv2
import numpy as np
import pytest
try:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
except ImportError:  # the chromium fixture fails each test with the command that installs it
    ActionChains = By = Keys = None

from conceptfusion.synthetic import tabletop_boxes
from harness.demo.run import run_demo
from harness.demo.scoring import DemoConfig
from harness.viewer.server import ViewerServer

pytestmark = pytest.mark.browser

BOXES = {b.name: b for b in tabletop_boxes()}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer-page")
    run_demo(DemoConfig(encoder="color", frames=6, width=160, height=120), out)
    with ViewerServer(out / "map.npz", encoder="color") as srv:
        yield srv


@pytest.fixture(scope="module")
def page(chromium, server, wait_for):
    chromium.get(server.url)
    wait_for(chromium, "window.cfViewer && (window.cfViewer.ready || window.cfViewer.error)", what="viewer load")
    assert chromium.execute_script("return window.cfViewer.error") is None
    return chromium


def _ask(driver, wait_for, act, what):
    wait_for(driver, "!window.cfViewer.busy", what=what)
    driver.execute_script("window.cfViewer.lastError = null; window.__answers = window.cfViewer.answers;")
    act()
    wait_for(driver, "window.cfViewer.answers > window.__answers || window.cfViewer.lastError", what=what)
    return driver.execute_script("const s = window.cfViewer; return {answer: s.lastAnswer, error: s.lastError, "
                                 "boxes: s.boxes, mode: s.mode, answers: s.answers - window.__answers}")


def _type(driver, text):
    box = driver.find_element(By.ID, "text-query")
    box.clear()
    box.send_keys(text + Keys.ENTER)


def _inside(point, box, tol=0.02):
    return bool(np.all(np.abs(np.asarray(point) - box.center) <= np.asarray(box.size) / 2 + tol))


def test_page_draws_every_point_of_the_map(page, server, artifacts):
    info = json.loads(urllib.request.urlopen(server.url + "api/info").read())
    state = page.execute_script("const s = window.cfViewer; return {n: s.pointsDrawn, frames: s.frames}")
    assert state["n"] == info["num_points"] > 1000 and state["frames"] >= 1
    png = page.find_element(By.ID, "canvas").screenshot_as_png
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    background = np.array([0x1C, 0x17, 0x14])  # #14171c in BGR
    drawn = np.any(np.abs(img.astype(int) - background) > 12, axis=2).mean()
    assert drawn > 0.05, f"only {drawn:.1%} of the canvas differs from the background: nothing drawn"
    page.save_screenshot(str(artifacts / "viewer_loaded.png"))


def test_text_query_draws_the_found_region(page, wait_for, artifacts):
    out = _ask(page, wait_for, lambda: _type(page, "red"), "text query")
    assert out["error"] is None and out["answers"] == 1
    ans = out["answer"]
    assert ans["kind"] == "text" and ans["query"] == "red" and ans["found"]
    assert out["boxes"] == len(ans["regions"]) >= 1 and out["mode"] == "heat"
    assert _inside(ans["regions"][0]["median"], BOXES["red box"])
    el = page.find_element(By.ID, "answer")
    assert el.get_attribute("data-found") == "true" and el.get_attribute("data-regions") == str(len(ans["regions"]))
    assert 'Text query "red": found' in el.text
    page.save_screenshot(str(artifacts / "viewer_text_query.png"))


def test_absent_name_says_not_found(page, wait_for, artifacts):
    out = _ask(page, wait_for, lambda: _type(page, "pink"), "absent query")
    assert out["answer"]["query"] == "pink" and not out["answer"]["found"] and out["boxes"] == 0
    el = page.find_element(By.ID, "answer")
    assert el.get_attribute("data-found") == "false"
    assert 'Text query "pink": not found: ' in el.text and out["answer"]["reason"] in el.text
    page.save_screenshot(str(artifacts / "viewer_not_found.png"))


def test_empty_query_shows_a_message(page, wait_for):
    before = page.execute_script("return window.cfViewer.lastAnswer.query")
    out = _ask(page, wait_for, lambda: _type(page, "   "), "empty query")
    assert out["answers"] == 0 and "expected a description" in out["error"]
    status = page.find_element(By.ID, "status")
    assert "error" in status.get_attribute("class") and "expected a description" in status.text
    assert page.execute_script("return window.cfViewer.lastAnswer.query") == before  # the last answer stays


def test_click_on_a_point_asks_the_click_query(page, server, wait_for, artifacts):
    info = json.loads(urllib.request.urlopen(server.url + "api/info").read())
    m = info["sent_points"]
    pts = np.frombuffer(urllib.request.urlopen(server.url + "api/points").read()[: 12 * m], "<f4").reshape(m, 3)
    green = BOXES["green box"]
    index = int(np.argmin(np.linalg.norm(pts - (np.asarray(green.center) + [0, 0, green.size[2] / 2]), axis=1)))
    spot = page.execute_script(f"return window.cfViewer.projectPoint({index})")
    assert spot["visible"]
    canvas = page.find_element(By.ID, "canvas")
    rect = page.execute_script("const r = arguments[0].getBoundingClientRect(); "
                               "return {x: r.left + r.width / 2, y: r.top + r.height / 2}", canvas)
    picked = page.execute_script(f"return window.cfViewer.pickAt({spot['x']}, {spot['y']})")
    assert picked is not None and _inside(pts[picked], green)

    def click():
        ActionChains(page).move_to_element_with_offset(canvas, round(spot["x"] - rect["x"]),
                                                       round(spot["y"] - rect["y"])).click().perform()

    out = _ask(page, wait_for, click, "click query")
    ans = out["answer"]
    assert out["error"] is None and ans["kind"] == "click" and ans["found"]
    assert _inside(ans["clicked"], green) and _inside(ans["regions"][0]["median"], green)
    assert out["boxes"] == len(ans["regions"])
    page.save_screenshot(str(artifacts / "viewer_click_query.png"))


def test_image_upload_asks_the_image_query(page, wait_for, tmp_path, artifacts):
    red = np.zeros((48, 64, 3), np.uint8)
    red[:] = BOXES["red box"].color[::-1]  # BGR for OpenCV
    path = tmp_path / "red.png"
    cv2.imwrite(str(path), red)
    out = _ask(page, wait_for, lambda: page.find_element(By.ID, "image-file").send_keys(str(path)), "image query")
    ans = out["answer"]
    assert out["error"] is None and ans["kind"] == "image" and ans["query"] == "red.png (64x48)" and ans["found"]
    assert _inside(ans["regions"][0]["median"], BOXES["red box"])
    page.save_screenshot(str(artifacts / "viewer_image_query.png"))

    bad = tmp_path / "notes.png"
    bad.write_text("not an image at all")
    out = _ask(page, wait_for, lambda: page.find_element(By.ID, "image-file").send_keys(str(bad)), "bad upload")
    assert out["answers"] == 0 and "expected a PNG, JPEG, BMP or WebP image" in out["error"]
    assert "expected a PNG" in page.find_element(By.ID, "status").text
