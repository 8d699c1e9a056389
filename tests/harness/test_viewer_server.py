"""The map viewer's server, over plain HTTP: loopback only, no file outside the map's folder, the
query endpoints' answers on a fused box scene (colour encoder), and bad queries answered with a
message."""

import base64
import http.client
import json
import shutil
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from agents.concept_map import ConceptMapper
from conceptfusion.errors import HarnessError, MissingFileError
from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.perception.featurizer import OracleFeaturizer
from conceptfusion.synthetic import tabletop_boxes
from harness.demo.run import run_demo
from harness.demo.scoring import DemoConfig
from harness.viewer.queries import BadQueryError, MapQueries, decode_image
from harness.viewer.server import ViewerServer, resolve_inside

RED_BOX = next(b for b in tabletop_boxes() if b.name == "red box")
GREEN_BOX = next(b for b in tabletop_boxes() if b.name == "green box")


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """maps/map.npz (a fused box scene), maps/notes.txt, maps/other.map.npz, maps/not_a_map.npz,
    and outside the folder: secret.txt and outside.npz (a valid map)."""
    root = tmp_path_factory.mktemp("viewer")
    maps = root / "maps"
    run_demo(DemoConfig(encoder="color", frames=6, width=160, height=120), maps)
    for ply in maps.glob("*.ply"):
        ply.unlink()
    (maps / "notes.txt").write_text("beside the map")
    shutil.copy(maps / "map.npz", maps / "other.map.npz")
    np.savez(maps / "not_a_map.npz", x=np.zeros(3))
    (root / "secret.txt").write_text("outside")
    shutil.copy(maps / "map.npz", root / "outside.npz")
    return root


@pytest.fixture(scope="module")
def server(folders):
    with ViewerServer(folders / "maps" / "map.npz", encoder="color") as srv:
        yield srv


def _request(server, method, path, body=None, headers=None):
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    hdrs = {"Host": f"127.0.0.1:{server.port}", **(headers or {})}
    conn.request(method, path, body=body, headers=hdrs)  # the path goes out as written: no client clean-up
    res = conn.getresponse()
    data = res.read()
    conn.close()
    return res.status, data


def _post_json(server, path, obj):
    status, data = _request(server, "POST", path, json.dumps(obj).encode(), {"Content-Type": "application/json"})
    return status, json.loads(data)


def _png(rgb):
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]))
    assert ok
    return buf.tobytes()


def test_binds_loopback_only(folders):
    for host in ("0.0.0.0", "192.168.1.20", "example.org", ""):
        with pytest.raises(HarnessError, match="expected a loopback address"):
            ViewerServer(folders / "maps" / "map.npz", encoder="color", host=host)
    with pytest.raises(MissingFileError, match="map file not found"):
        ViewerServer(folders / "maps" / "missing.npz", encoder="color")
    with pytest.raises(HarnessError, match="oracle-open: grounds descriptions in a live scene's ground truth"):
        ViewerServer(folders / "maps" / "map.npz", encoder="oracle-open")


def test_serves_the_page_and_files_of_the_map_folder(server):
    status, page = _request(server, "GET", "/")
    assert status == 200 and b'src="/static/viewer.js"' in page
    status, js = _request(server, "GET", "/static/vendor/three.module.min.js")
    assert status == 200 and b"Three.js Authors" in js[:200]
    assert _request(server, "GET", "/files/notes.txt") == (200, b"beside the map")


@pytest.mark.parametrize("path", [
    "/files/../secret.txt", "/files/%2e%2e/secret.txt", "/files/..%2fsecret.txt", "/files/sub/../../secret.txt",
    "/files//etc/passwd", "/files/%2Fetc%2Fpasswd", "/files/..\\secret.txt", "/static/../server.py",
    "/static/../../../../etc/passwd", "/api/info?map=../outside.npz", "/api/points?map=%2E%2E/outside.npz",
])
def test_refuses_paths_outside_the_folder(server, path):
    status, body = _request(server, "GET", path)
    assert status == 403, (path, status, body[:200])
    assert body.strip() != b"outside" and b"root:" not in body  # neither file's content came back


def test_refuses_absolute_paths_and_links_out(server, folders):
    status, _ = _request(server, "GET", f"/api/info?map={folders / 'outside.npz'}")
    assert status == 403
    link = folders / "maps" / "link.txt"
    link.symlink_to(folders / "secret.txt")
    try:
        assert _request(server, "GET", "/files/link.txt")[0] == 403
    finally:
        link.unlink()
    assert _request(server, "GET", "/files/nothing-here.txt")[0] == 404
    assert _request(server, "GET", "/no/such/page")[0] == 404
    with pytest.raises(PermissionError):
        resolve_inside(folders / "maps", "C:/windows/win.ini")


def test_refuses_requests_for_other_host_names(server):
    status, body = _request(server, "GET", "/api/info", headers={"Host": "attacker.example"})
    assert status == 403 and b"loopback" in body


def test_info_lists_maps_of_the_folder_and_points_payload(server):
    status, data = _request(server, "GET", "/api/info")
    info = json.loads(data)
    assert status == 200 and info["ok"] and info["encoder"] == "color"
    assert info["maps"] == ["map.npz", "other.map.npz"]  # not_a_map.npz is left out
    assert info["sent_points"] == info["num_points"] > 1000 and len(info["palette"]) == 255
    status, payload = _request(server, "GET", "/api/points")
    m = info["sent_points"]
    assert status == 200 and len(payload) == 15 * m
    pts = np.frombuffer(payload[: 12 * m], "<f4").reshape(m, 3)
    assert np.allclose(pts.min(axis=0), info["bounds_min"], atol=1e-5)
    assert json.loads(_request(server, "GET", "/api/info?map=other.map.npz")[1])["map"] == "other.map.npz"


def test_text_query_finds_the_object_and_says_not_found_for_an_absent_one(server):
    status, ans = _post_json(server, "/api/query", {"text": "red"})
    assert status == 200 and ans["found"] and ans["kind"] == "text"
    median = np.array(ans["regions"][0]["median"])
    assert np.all(np.abs(median - RED_BOX.center) <= np.array(RED_BOX.size) / 2 + 0.02)
    lo, hi = np.array(ans["regions"][0]["aabb_min"]), np.array(ans["regions"][0]["aabb_max"])
    assert np.all(lo <= median) and np.all(median <= hi)
    heat = np.frombuffer(base64.b64decode(ans["heat"]), np.uint8)
    assert heat[heat < 255].max() == 254 and (heat == 255).any() and heat.size == json.loads(_request(server, "GET", "/api/info")[1])["sent_points"]
    status, ans = _post_json(server, "/api/query", {"text": "pink"})
    assert status == 200 and not ans["found"] and ans["regions"] == [] and "region" in ans["reason"]


@pytest.mark.parametrize("body, message", [
    ({"text": ""}, "expected a description"), ({"text": "   "}, "expected a description"),
    ({"text": 3}, "expected a description"), ({}, "expected a description"),
])
def test_bad_text_queries_get_a_message(server, body, message):
    status, ans = _post_json(server, "/api/query", body)
    assert status == 400 and not ans["ok"] and message in ans["error"]


def test_bad_request_bodies_get_a_message(server):
    status, data = _request(server, "POST", "/api/query", b"not json", {"Content-Type": "application/json"})
    assert status == 400 and "expected a JSON object" in json.loads(data)["error"]
    status, data = _request(server, "POST", "/api/query", b"[1, 2]", {"Content-Type": "application/json"})
    assert status == 400 and "expected a JSON object, got list" in json.loads(data)["error"]
    for bad in ({"index": -1}, {"index": 10**9}, {"index": "3"}, {"index": True}, {}):
        status, ans = _post_json(server, "/api/click", bad)
        assert status == 400 and "expected a point index" in ans["error"]
    status, data = _request(server, "POST", "/api/image", b"GIF89a-but-not-really", {"Content-Type": "image/gif"})
    assert status == 400 and "expected a PNG, JPEG, BMP or WebP image, got 21 bytes" in json.loads(data)["error"]
    status, data = _request(server, "POST", "/api/image", b"", {"Content-Type": "image/png"})
    assert status == 400 and "empty upload" in json.loads(data)["error"]
    assert _request(server, "POST", "/api/nothing", b"{}")[0] == 404
    # the server still answers after all that
    assert _post_json(server, "/api/query", {"text": "red"})[1]["found"]


def test_click_query_on_a_point_of_the_green_box_finds_the_green_box(server):
    _, data = _request(server, "GET", "/api/info")
    m = json.loads(data)["sent_points"]
    pts = np.frombuffer(_request(server, "GET", "/api/points")[1][: 12 * m], "<f4").reshape(m, 3)
    top = GREEN_BOX.center + np.array([0, 0, GREEN_BOX.size[2] / 2])
    index = int(np.argmin(np.linalg.norm(pts - top, axis=1)))
    status, ans = _post_json(server, "/api/click", {"index": index})
    assert status == 200 and ans["kind"] == "click" and ans["found"]
    assert np.allclose(ans["clicked"], pts[index], atol=1e-3)
    best = ans["regions"][0]
    assert np.all(np.abs(np.array(best["median"]) - GREEN_BOX.center) <= np.array(GREEN_BOX.size) / 2 + 0.02)
    assert np.all(np.array(best["aabb_min"]) - 0.01 <= pts[index]) and np.all(pts[index] <= np.array(best["aabb_max"]) + 0.01)


def test_image_query_with_an_uploaded_picture(server):
    red = np.zeros((40, 60, 3), np.uint8)
    red[:] = RED_BOX.color
    status, data = _request(server, "POST", "/api/image?name=red.png", _png(red), {"Content-Type": "image/png"})
    ans = json.loads(data)
    assert status == 200 and ans["kind"] == "image" and ans["found"] and ans["query"] == "red.png (60x40)"
    assert np.linalg.norm(np.array(ans["regions"][0]["median"]) - RED_BOX.center) < 0.1


def test_decode_image_reads_grey_and_alpha_and_refuses_text():
    grey = cv2.imencode(".png", np.full((5, 7), 200, np.uint8))[1].tobytes()
    assert decode_image(grey).shape == (5, 7, 3)
    rgba = cv2.imencode(".png", np.dstack([np.zeros((4, 4, 3), np.uint8), np.full((4, 4), 255, np.uint8)]))[1].tobytes()
    assert decode_image(rgba).shape == (4, 4, 3)
    with pytest.raises(BadQueryError, match="no image decoder reads"):
        decode_image(b"hello, not an image")
    with pytest.raises(BadQueryError, match="expected the bytes of an image file, got str"):
        decode_image("red.png")


class _TextOnly:
    """The colour encoder without its image tower."""

    def __init__(self):
        self._enc = ColorNameEncoder()
        self.dim = self._enc.dim

    def encode_text(self, texts):
        return self._enc.encode_text(texts)


def test_text_only_encoder_and_dimension_mismatch_are_explained(folders):
    q = MapQueries(folders / "maps" / "map.npz", ConceptMapper(OracleFeaturizer(_TextOnly(), score_floor=None)),
                   encoder_name="text-only")
    assert q.text("red")["found"]
    with pytest.raises(BadQueryError, match="embeds text only"):
        q.image(_png(np.zeros((4, 4, 3), np.uint8)))
    wrong = SimpleNamespace(featurizer=SimpleNamespace(dim=7))
    with pytest.raises(HarnessError, match="have 32 dimensions, the encoder 'x' gives 7"):
        MapQueries(folders / "maps" / "map.npz", wrong, encoder_name="x")


def test_large_maps_are_thinned_to_max_points(folders):
    from agents.builtin import make_mapper

    q = MapQueries(folders / "maps" / "map.npz", make_mapper("color"), encoder_name="color", max_points=500)
    assert len(q.points_payload()) == 15 * 500 and q.info()["sent_points"] == 500
    assert len(base64.b64decode(q.text("red")["heat"])) == 500
    assert len(np.unique(q.sent_n)) == 500 and q.sent_n.max() < len(q.map)
    full = MapQueries(folders / "maps" / "map.npz", make_mapper("color"), encoder_name="color")
    assert np.array_equal(np.sort(full.sent_n), np.arange(len(full.map)))  # every point, in a shuffled order
    assert not np.array_equal(full.sent_n, np.arange(len(full.map)))


def test_viewer_cli_refuses_bad_settings(folders, capsys):
    from harness.cli import main

    assert main(["view", str(folders / "maps" / "map.npz"), "--encoder", "color", "--host", "0.0.0.0"]) == 2
    assert "expected a loopback address" in capsys.readouterr().err
    assert main(["view", str(folders / "maps" / "not_a_map.npz"), "--encoder", "color"]) == 2
    assert "cfharness view:" in capsys.readouterr().err


def test_answers_equal_the_agents_mapper_on_the_plain_map(folders):
    """The viewer's remembered scores change nothing: the same regions as an agent's mapper."""
    from agents.builtin import make_mapper
    from conceptfusion.map.persistence import load_map

    q = MapQueries(folders / "maps" / "map.npz", make_mapper("color"), encoder_name="color")
    plain = make_mapper("color")
    plain.map = load_map(folders / "maps" / "map.npz")
    for text in ("red", "green", "pink", "red"):  # "red" twice: the second from remembered scores
        ours, theirs = q.text(text), plain.locate(text)
        assert ours["found"] == theirs.found and ours["reason"] == theirs.reason
        assert [r["num_points"] for r in ours["regions"]] == [r.num_points for r in theirs.regions]
        assert all(np.allclose(a["median"], b.median, atol=1e-4) for a, b in zip(ours["regions"], theirs.regions))


def _with_meta(src, dst, meta):
    from conceptfusion.map.persistence import load_map, save_map

    return save_map(load_map(src), dst, meta=meta)


def test_the_viewer_asks_with_the_encoder_floor_and_lookup_the_map_records(folders, tmp_path):
    """A map file records how its agent asked it; the viewer opens it that way with no flag, and
    says so when told otherwise (or when the file records nothing)."""
    from conceptfusion.errors import UnknownNameError
    from harness.viewer.server import perception_for

    demo = folders / "maps" / "map.npz"
    how = perception_for(demo)  # the demo records its encoder
    assert (how.encoder, how.lookup, how.notes, how.min_score) == ("color", "plain", (), (None,))
    strict = _with_meta(demo, tmp_path / "strict.map.npz",
                        {"encoder": "color", "setting": "tabletop", "min_score": 0.999, "lookup": "present", "name_only": True})
    with ViewerServer(strict) as srv:
        q = srv.open_map(None)
        info = q.info()
        assert (srv.encoder_name, info["encoder"], info["lookup"], info["score_floor"]) == ("color", "color", "present", 0.999)
        plain = q.text("red box", lookup="plain")
        assert not plain["found"] and "floor" in plain["reason"]  # the recorded floor applies
        agent = q.text("red box")  # the map's own lookup: presumed present, as its agent asked
        assert agent["found"] and agent["lookup"] == "present" and agent["presumed"] in ("under_floor", "name_only")
        status, body = _post_json(srv, "/api/query", {"text": "red box", "lookup": "guess"})
        assert status == 400 and "lookup: expected one of plain, present" in body["error"]
    unrecorded = _with_meta(demo, tmp_path / "old.map.npz", {})
    assert "does not record its encoder" in perception_for(unrecorded, None).notes[0]
    assert perception_for(unrecorded, "color").notes == ()
    assert "built with 'color'" in perception_for(demo, "embedded").notes[0]
    alien = _with_meta(demo, tmp_path / "alien.map.npz", {"encoder": "my-clip"})
    with pytest.raises(UnknownNameError, match=r"records the encoder 'my-clip'.*--import"):
        ViewerServer(alien)
