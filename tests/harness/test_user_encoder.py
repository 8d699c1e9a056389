"""A researcher's own encoder, end to end: a plugin module written here registers a tiny
deterministic encoder (colour histogram images, bag-of-words texts, unit rows, dim 32); the
harness runs an episode with it (``--import``, ``--encoder``), ``cfharness list`` shows it, the
viewer answers text queries on a map built with it, and an encoder answering off the unit sphere
fails its episode with the wrapper's message."""

import http.client
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conceptfusion import RGBDFrame, load_map, save_map
from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.perception import registry
from conceptfusion.synthetic import orbit_poses, render_boxes, tabletop_boxes

REPO = Path(__file__).resolve().parents[2]

PLUGIN = '''
"""A tiny deterministic encoder: images as a histogram over 8 prototype colours, texts as their
colour words plus hashed other words; unit rows of 32 numbers."""
import hashlib
import re

import numpy as np

from conceptfusion import register_encoder

DIM = 32
COLOURS = {"red": (200, 30, 30), "green": (40, 160, 60), "blue": (30, 60, 200), "yellow": (230, 210, 40),
           "orange": (240, 130, 30), "purple": (130, 50, 160), "white": (240, 240, 240), "gray": (128, 128, 128)}
PROTOS = np.array(list(COLOURS.values()), np.float64)
SCALE = 1.0  # the broken variant answers rows of another length


def unit(x):
    return (SCALE * x / np.linalg.norm(x, axis=1, keepdims=True)).astype(np.float32)


class TinyEncoder:
    dim = DIM

    def encode_image(self, images):
        out = np.zeros((len(images), DIM))
        for i, img in enumerate(images):
            px = img.reshape(-1, 3).astype(np.float64)
            nearest = np.argmin(((px[:, None, :] - PROTOS[None]) ** 2).sum(-1), axis=1)
            out[i, : len(PROTOS)] = np.bincount(nearest, minlength=len(PROTOS)) / len(px)
        out[:, -1] = 1e-3
        return unit(out)

    def encode_text(self, texts):
        out = np.zeros((len(texts), DIM))
        for i, text in enumerate(texts):
            for word in re.findall("[a-z]+", text.lower()):
                if word in COLOURS:
                    out[i, list(COLOURS).index(word)] += 1.0
                else:
                    h = int.from_bytes(hashlib.sha256(word.encode()).digest()[:4], "little")
                    out[i, len(COLOURS) + h % (DIM - len(COLOURS))] += 0.5
        out[:, -1] += 1e-3
        return unit(out)


register_encoder(NAME, lambda arg: TinyEncoder(), description="tiny colour histogram / bag-of-words test encoder")
'''


def _write_plugin(folder: Path, module: str, name: str, scale: float = 1.0) -> str:
    (folder / f"{module}.py").write_text(f"NAME = {name!r}\n" + PLUGIN.replace("SCALE = 1.0", f"SCALE = {scale!r}"))
    return module


def _run_episode(tmp_path: Path, module: str, encoder: str) -> dict:
    out = tmp_path / f"run-{encoder}"
    env = {**os.environ, "MUJOCO_GL": "egl", "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "harness.cli", "run", "--import", module, "--encoder", encoder, "--suite", "rearrange",
                           "--agent", "map-pusher", "--limit", "1", "--backend", "serial", "--out", str(out), "--no-report"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = (out / "results.jsonl").read_text().splitlines()
    assert len(lines) == 1
    return json.loads(lines[0])


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """The plugin imported in this process (as ``--import`` would), the registry restored after."""
    saved = dict(registry.ENCODERS)
    module = _write_plugin(tmp_path, "tiny_cf_plugin", "tiny-test")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield module
    sys.modules.pop(module, None)
    registry.ENCODERS.clear()
    registry.ENCODERS.update(saved)


def test_an_episode_runs_with_the_registered_encoder(tmp_path):
    rec = _run_episode(tmp_path, _write_plugin(tmp_path, "tiny_cf_plugin", "tiny-test"), "tiny-test")
    assert rec["encoder"] == "tiny-test" and rec["agent_kwargs"]["encoder"] == "tiny-test"
    assert rec["status"] == "ok", rec["error"]
    assert isinstance(rec["metrics"]["success"], bool)


def test_an_encoder_answering_non_unit_rows_fails_its_episode_saying_why(tmp_path):
    rec = _run_episode(tmp_path, _write_plugin(tmp_path, "tiny_cf_bad", "tiny-bad", scale=3.2), "tiny-bad")
    assert rec["encoder"] == "tiny-bad" and rec["status"] == "failed"
    assert "encoder 'tiny-bad': encode_image row 0 has norm 3.2, expected unit vectors" in rec["error"]


def test_cfharness_list_shows_an_imported_encoder(plugin, capsys):
    from harness.cli import main

    assert main(["list", "--import", plugin]) == 0
    listed = capsys.readouterr().out
    assert "tiny-test        tiny colour histogram / bag-of-words test encoder" in listed


def test_the_viewer_answers_text_queries_on_a_map_built_with_it(plugin, tmp_path):
    from agents import make_mapper
    from harness.viewer.server import ViewerServer

    importlib.import_module(plugin)
    boxes = tabletop_boxes()
    red = next(b for b in boxes if b.name == "red box")
    K = intrinsics_from_fovy(60.0, 160, 120)
    mapper = make_mapper("tiny-test")
    for pose in orbit_poses((0.0, 0.0, 0.45), 1.3, 0.8, 3):
        frame = render_boxes(boxes, K, pose, 120, 160)
        mapper.integrate(RGBDFrame(rgb=frame.rgb, depth=frame.depth, K=frame.K, cam_to_world=frame.cam_to_world))
    path = save_map(mapper.map, tmp_path / "tiny.map.npz")
    assert load_map(path).feature_dim == 32

    with ViewerServer(path, encoder="tiny-test") as server:
        info = server.open_map(None).info()
        assert info["encoder"] == "tiny-test" and info["image_queries"] is True
        conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=60)
        conn.request("POST", "/api/query", body=json.dumps({"text": "red box"}).encode(),
                     headers={"Host": f"127.0.0.1:{server.port}", "Content-Type": "application/json"})
        res = conn.getresponse()
        status, answer = res.status, json.loads(res.read())
        conn.close()
    assert status == 200 and answer["ok"] and answer["found"], answer["reason"]
    assert np.isfinite(answer["best_relevancy"]) and answer["regions"][0]["score"] > 0
    assert np.linalg.norm(np.subtract(answer["regions"][0]["median"], red.center)) < 0.1


def test_cfharness_view_imports_the_plugin_first(tmp_path, capsys):
    from harness.cli import main

    assert main(["view", str(tmp_path / "missing.map.npz"), "--import", "no_such_cf_plugin", "--encoder", "tiny-test"]) == 2
    assert "--import 'no_such_cf_plugin': cannot import 'no_such_cf_plugin'" in capsys.readouterr().err
