"""The map viewer in headless Chromium: frames per second drawing a 1M-point map, and the
end-to-end latency of a text query (typed in the page, answered, heatmap and boxes drawn).

    python benchmarks/bench_viewer.py                      # the demo's tabletop map, tiled to 1M points
    python benchmarks/bench_viewer.py --map runs/demo/map.npz --points 1000000 --seconds 5
    python benchmarks/bench_viewer.py --screenshot docs/images/viewer.png --points 0

Targets: interactive frame rates for a 1M-point map; a text query under 0.3 s end to end.

The map: ``--map`` (default ``runs/demo/map.npz``, built with ``cfharness demo`` when missing,
about a minute), copied side by side on a grid until it holds ``--points`` points (features
and all, so queries cost what they would on a map that size; ``--points 0`` keeps it as is).
Frames per second: the page turns the camera every frame (``window.cfViewer.spin``) and counts
the frames it draws over ``--seconds``. Without a GPU, Chromium draws WebGL with SwiftShader on the
CPU, so the figure is a floor, not what a desktop browser does. Query latency: from the form's
submit to the frame after the answer is drawn, measured in the page (``window.cfViewer.timing``),
and the server's share of it.
"""

from __future__ import annotations

import argparse
import math
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.persistence import load_map, save_map
from harness.viewer.server import ViewerServer

DEMO_MAP = Path("runs/demo/map.npz")
QUERIES = ("black can", "blue box", "brown mug", "orange ball", "pink box", "purple bottle", "green book")


def tiled_map(fmap: PointFusionMap, min_points: int) -> PointFusionMap:
    """``fmap`` copied on a grid in x-y (0.2 m apart) until it holds at least ``min_points`` points."""
    header, arrays = fmap.state_dict()
    n = header["num_points"]
    copies = max(1, math.ceil(min_points / max(n, 1)))
    cols = math.ceil(math.sqrt(copies))
    pts = fmap.points
    step = pts[:, :2].max(axis=0) - pts[:, :2].min(axis=0) + 0.2
    geo = []
    for k in range(copies):
        g = arrays["geometry"].copy()
        g[:, 0] += (k % cols) * step[0]
        g[:, 1] += (k // cols) * step[1]
        geo.append(g)
    out = {"geometry": np.concatenate(geo), "feat_bank": arrays["feat_bank"]}
    for name in ("feat_point_ids", "feat_point_w", "feat_point_gram", "feat_point_sq"):
        out[name] = np.concatenate([arrays[name]] * copies)
    return PointFusionMap.from_state_dict({**header, "num_points": n * copies}, out)


def chromium(width: int = 1280, height: int = 800):
    """Headless Chromium (the system's chromium + chromedriver) through Selenium."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    binary, driver = shutil.which("chromium") or shutil.which("chromium-browser"), shutil.which("chromedriver")
    if not binary or not driver:
        raise SystemExit("bench_viewer: needs chromium and chromedriver on PATH (apt-get install chromium chromium-driver)")
    opts = webdriver.ChromeOptions()
    opts.binary_location = binary
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--window-size={width},{height}",
                "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--enable-gpu-rasterization",
                "--disable-frame-rate-limit", "--disable-gpu-vsync"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(driver), options=opts)


def _wait(driver, script: str, timeout: float = 120.0):
    deadline = time.monotonic() + timeout
    while not driver.execute_script("return " + script):
        if time.monotonic() > deadline:
            raise TimeoutError(script)
        time.sleep(0.02)


def _query(driver, text: str) -> dict:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    _wait(driver, "!window.cfViewer.busy")
    driver.execute_script("window.__n = window.cfViewer.answers; window.cfViewer.lastError = null;")
    box = driver.find_element(By.ID, "text-query")
    box.clear()
    box.send_keys(text + Keys.ENTER)
    _wait(driver, "window.cfViewer.answers > window.__n || window.cfViewer.lastError")
    return driver.execute_script("const s = window.cfViewer; return {timing: s.timing, found: s.lastAnswer.found, "
                                 "error: s.lastError}")


def _fps(driver, seconds: float, lod: bool) -> tuple[float, float]:
    """(frames/s, mean points drawn a frame) while the camera turns, counted in the page."""
    driver.execute_script(f"window.cfViewer.lod = {'true' if lod else 'false'}; window.cfViewer.spin = true;")
    time.sleep(1.0)  # settle (the level of detail adapts)
    driver.execute_script("window.__f0 = window.cfViewer.frames; window.__t0 = performance.now(); window.__d = 0; "
                          "window.__tick = () => { window.__d += window.cfViewer.drawnLast; "
                          "if (window.cfViewer.spin) requestAnimationFrame(window.__tick); }; requestAnimationFrame(window.__tick);")
    time.sleep(seconds)
    out = driver.execute_script("const s = window.cfViewer; s.spin = false; const n = s.frames - window.__f0; "
                                "return {n, dt: (performance.now() - window.__t0) / 1000, drawn: window.__d}")
    return out["n"] / out["dt"], out["drawn"] / max(out["n"], 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--map", type=Path, default=DEMO_MAP)
    ap.add_argument("--encoder", default="embedded")
    ap.add_argument("--points", type=int, default=1_000_000, help="tile the map to at least this many points (0: as is)")
    ap.add_argument("--seconds", type=float, default=5.0, help="how long to count frames")
    ap.add_argument("--screenshot", type=Path, help="save a screenshot of the page after the first query")
    args = ap.parse_args()

    if not args.map.is_file():
        from harness.demo.run import run_demo
        from harness.demo.scoring import DemoConfig

        print(f"{args.map} missing: building it with the demo ({args.encoder}) ...")
        run_demo(DemoConfig(encoder=args.encoder), args.map.parent)
    base = load_map(args.map)
    with tempfile.TemporaryDirectory() as tmp:
        path = args.map
        if args.points > len(base):
            path = Path(tmp) / "tiled.npz"
            save_map(tiled_map(base, args.points), path)
        t0 = time.perf_counter()
        server = ViewerServer(path, encoder=args.encoder).start()
        print(f"map {path.name}: {len(load_map(path)):,} points; server ready in {time.perf_counter() - t0:.1f} s")
        driver = chromium()
        try:
            t0 = time.perf_counter()
            driver.get(server.url)
            _wait(driver, "window.cfViewer && (window.cfViewer.ready || window.cfViewer.error)")
            state = driver.execute_script("return {n: window.cfViewer.pointsDrawn, gl: window.cfViewer.gl, "
                                          "error: window.cfViewer.error}")
            if state["error"]:
                raise SystemExit(f"the page failed: {state['error']}")
            print(f"page loaded and drew {state['n']:,} points in {time.perf_counter() - t0:.2f} s; WebGL: {state['gl']}")

            _query(driver, QUERIES[0])  # warm-up: text tower, compiled kernels
            lat, server_ms, answered, full = [], [], [], []
            for text in QUERIES:
                out = _query(driver, text)
                if out["error"]:
                    print(f"  {text!r}: {out['error']}")
                    continue
                lat.append(out["timing"]["total_ms"])
                server_ms.append(out["timing"]["server_ms"])
                answered.append(out["timing"]["request_ms"])
                full.append(out["timing"]["full_ms"])
                print(f"  {text!r}: {'found' if out['found'] else 'not found'}: server {out['timing']['server_ms']:.0f} ms, "
                      f"answer in the page {out['timing']['request_ms']:.0f} ms, drawn {out['timing']['total_ms']:.0f} ms, "
                      f"every point redrawn {out['timing']['full_ms']:.0f} ms")
            med = statistics.median
            print(f"text query (target < 300 ms end to end), medians: server {med(server_ms):.0f} ms, answer in the page "
                  f"{med(answered):.0f} ms, drawn {med(lat):.0f} ms (worst {max(lat):.0f} ms), every point redrawn "
                  f"{med(full):.0f} ms")
            if args.screenshot:
                _query(driver, "brown mug")
                args.screenshot.parent.mkdir(parents=True, exist_ok=True)
                driver.save_screenshot(str(args.screenshot))
                print(f"screenshot: {args.screenshot}")

            for lod in (False, True):
                fps, drawn = _fps(driver, args.seconds, lod)
                what = "every point every frame" if not lod else f"moving view's sample, {drawn:,.0f} points a frame"
                print(f"drawing {state['n']:,} points, camera turning ({what}): {fps:.1f} frames/s")
        finally:
            driver.quit()
            server.close()


if __name__ == "__main__":
    main()
