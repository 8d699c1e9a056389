"""The spatial suite: its paraphrase templates (checked on load, a fresh share the parsers never
saw), questions from the scene graph for all eight comparators, parse scoring, and the figures
that must hold with privileged (oracle) features."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.spatial.parser import cannot_parse, parsed
from conceptfusion.errors import HarnessError, UnknownNameError
from conceptfusion.spatial.comparators import COMPARATOR_NAMES
from harness.maps.scan import load_shipped_scene, scan_scene
from harness.maps.spatial import PER_SCENE, QUESTION_TYPES, distance_ok, generate_questions, parse_outcome, spatial_metrics
from harness.maps.spatial_templates import MIN_TEMPLATES, TEMPLATES_PATH, load_templates, normalise_text, template_pattern
from harness.runner.map_jobs import MapJob, run_map_job

ROOT = Path(__file__).resolve().parents[2]
DEV_QUESTIONS = sorted((ROOT / "tests" / "agents" / "data").glob("spatial_questions*.jsonl"))
EXEMPLARS = ROOT / "agents" / "spatial" / "relations.json"
HOUSEHOLD = "household-0000"


def _development_texts() -> list[str]:
    """Every question and exemplar the parsers were developed or measured on, normalised."""
    texts = []
    for path in DEV_QUESTIONS:
        texts += [normalise_text(json.loads(line)["question"]) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]
    for items in json.loads(EXEMPLARS.read_text(encoding="utf-8"))["classes"].values():
        texts += [normalise_text(text) for text, _ in items]
    return texts


def test_templates_cover_every_comparator():
    templates = load_templates()
    assert tuple(templates) == COMPARATOR_NAMES == QUESTION_TYPES
    for comparator, items in templates.items():
        assert len(items) >= MIN_TEMPLATES and all(t.comparator == comparator for t in items)
    t = templates["isBigger"][2]
    assert t.text == "Is the {b} smaller than the {a}?" and t.fill("sofa", "mug") == "Is the mug smaller than the sofa?"


def test_fresh_templates_are_phrased_unlike_the_parser_development_set():
    assert len(DEV_QUESTIONS) >= 1 and EXEMPLARS.exists()
    texts = _development_texts()
    assert len(texts) > 200
    templates = load_templates()
    for comparator, items in templates.items():
        fresh = [t for t in items if t.fresh]
        assert len(fresh) >= 0.3 * len(items), f"{comparator}: only {len(fresh)} of {len(items)} templates are fresh"
        for t in fresh:
            pattern = template_pattern(t)
            hits = [x for x in texts if pattern.search(x)]
            assert not hits, f"template {t.id} ({t.text!r}) is in the development set: {hits[:3]}"
    # the search finds what is there: a common phrasing, and a question with other names
    assert any(template_pattern(templates["howFar"][0]).search(x) for x in texts)
    assert template_pattern("Is the {a} on top of the {b}?").search(normalise_text("Hey, is the red mug on top of the dining table?"))
    assert template_pattern("Is the {a} off toward the {b}'s left?").search("is x off toward y 's left")


def _write(tmp_path, templates) -> Path:
    p = tmp_path / "t.json"
    p.write_text(json.dumps({"about": "test", "templates": templates}))
    return p


def _good() -> dict:
    return {c: [{"id": f"{c}-{k}", "text": f"q{k} {{a}} {c} {{b}}?", "fresh": k < 3} for k in range(MIN_TEMPLATES)]
            for c in COMPARATOR_NAMES}


def test_bad_template_files_are_refused_with_clear_errors(tmp_path):
    assert sum(len(v) for v in load_templates(_write(tmp_path, _good())).values()) == 8 * MIN_TEMPLATES
    t = _good()
    t["howFar"] = t["howFar"][:3]
    with pytest.raises(HarnessError, match=r"howFar: expected a list of at least 10 templates, got 3"):
        load_templates(_write(tmp_path, t))
    t = _good()
    t["isBiger"] = t.pop("isBigger")
    with pytest.raises(UnknownNameError, match=r"unknown comparator 'isBiger'; did you mean 'isBigger'"):
        load_templates(_write(tmp_path, t))
    t = _good()
    t["under"][4]["text"] = "is the {a} under it?"
    with pytest.raises(HarnessError, match=r"under\[4\] \(under-4\): text must hold both slots \{a\} and \{b\}"):
        load_templates(_write(tmp_path, t))
    t = _good()
    t["under"][4]["text"] = "is the {a} under the {c} {b}?"
    with pytest.raises(HarnessError, match=r"only the slots \{a\} and \{b\} may use braces"):
        load_templates(_write(tmp_path, t))
    t = _good()
    t["onTopOf"][1]["id"] = "howFar-0"
    with pytest.raises(HarnessError, match=r"onTopOf\[1\]: id 'howFar-0' already used by a howFar template"):
        load_templates(_write(tmp_path, t))
    t = _good()
    t["onTopOf"][1]["fresh"] = "yes"
    with pytest.raises(HarnessError, match=r"'fresh' expected true or false, got 'yes'"):
        load_templates(_write(tmp_path, t))
    t = _good()
    del t["canFitInside"]
    with pytest.raises(HarnessError, match=r"no templates for \['canFitInside'\]"):
        load_templates(_write(tmp_path, t))
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(HarnessError, match=r"not valid JSON"):
        load_templates(tmp_path / "bad.json")
    with pytest.raises(HarnessError, match=r"no such file"):
        load_templates(tmp_path / "missing.json")
    assert TEMPLATES_PATH.exists()


def test_parse_outcome_accepts_the_expected_call_or_its_mirror():
    q = {"type": "under", "a": "table", "b": "red mug"}
    assert parse_outcome(parsed("under", "the table", "red mug"), q) == "exact"
    assert parse_outcome(parsed("onTopOf", "red mug", "table"), q) == "equivalent"
    assert parse_outcome(parsed("onTopOf", "table", "red mug"), q) == "wrong"
    assert parse_outcome(parsed("under", "table", "mug"), q) == "wrong"
    assert parse_outcome(cannot_parse("no"), q) == "refused"
    left = {"type": "isToTheLeft", "a": "cup", "b": "bowl"}
    assert parse_outcome(parsed("isToTheRight", "bowl", "cup"), left) == "equivalent"
    assert parse_outcome(parsed("isBigger", "bowl", "cup"), {"type": "isBigger", "a": "cup", "b": "bowl"}) == "wrong"


def test_metrics_split_parse_errors_from_answer_errors():
    def q(kind, parse, correct, found=True, fresh=False, gt=1.0):
        return {"type": kind, "parse": parse, "correct": correct, "found": found, "fresh": fresh, "gt": gt}

    m = spatial_metrics([q("howFar", "exact", True), q("howFar", "refused", False, found=False, fresh=True),
                         q("under", "equivalent", False, found=False, gt=True), q("under", "wrong", False, fresh=True, gt=False)])
    assert m["accuracy"] == 0.25 and m["accuracy_parsed"] == 0.5 and m["parse_rate"] == 0.5 and m["parse_fail_rate"] == 0.25
    assert m["notfound_rate"] == 0.5 and m["accuracy_fresh"] == 0.0 and m["accuracy_seen"] == 0.5
    assert m["acc_howFar"] == 0.5 and m["n_under"] == 2 and m["acc_isBigger"] is None and m["n_questions"] == 4
    # chance references on the same questions: one of the two yes/no answers is yes; distances count wrong
    assert m["chance_always_yes"] == 0.25 and m["chance_random"] == 0.25


@pytest.fixture(scope="module")
def household_scan():
    return scan_scene(load_shipped_scene(HOUSEHOLD), frames=24, width=160, height=120)


def test_question_generation_gives_every_type(household_scan):
    qs = generate_questions(household_scan, seed=0)
    assert {q["type"] for q in qs} == set(QUESTION_TYPES)
    assert qs == generate_questions(household_scan, seed=0)
    assert qs != generate_questions(household_scan, seed=1)
    assert all(isinstance(q["gt"], bool) for q in qs if q["type"] != "howFar")
    for kind in ("onTopOf", "under", "isToTheLeft", "isBigger"):
        assert any(q["gt"] is True for q in qs if q["type"] == kind) and any(q["gt"] is False for q in qs if q["type"] == kind)
    templates = {t.id: t for items in load_templates().values() for t in items}
    for q in qs:
        t = templates[q["template"]]
        assert t.comparator == q["type"] and q["fresh"] == t.fresh and q["question"] == t.fill(q["a"], q["b"])
        assert q["expected"] == f"{q['type']}({q['a']}, {q['b']})"
    per_type = {k: sum(q["type"] == k for q in qs) for k in QUESTION_TYPES}
    assert max(per_type.values()) <= PER_SCENE and len(qs) <= PER_SCENE * len(QUESTION_TYPES)
    assert any(q["fresh"] for q in qs) and not all(q["fresh"] for q in qs)
    # under(a, b) asks whether b rests on a
    on = {(q["a"], q["b"]) for q in qs if q["type"] == "onTopOf" and q["gt"]}
    support = {(a, b) for a, b in household_scan.graph["supported_by"]}
    names = {o.id: o.name for o in household_scan.scene.objects}
    assert on <= {(names[a], names.get(b, b)) for a, b in support} | {(names[a], f["name"]) for a, b in support
                                                                      for f in household_scan.graph.get("furniture", []) if f["id"] == b}


def test_spatial_3d_map_answers_at_least_as_well_as_a_single_frame():
    opts = {"frames": 24, "width": 160, "height": 120}
    recs = {a: run_map_job(MapJob(run_id="t", suite="spatial", agent=a, encoder="oracle", scene_id=HOUSEHOLD, options=opts))[0]
            for a in ("map-3d", "frame-2.5d")}
    m3, m25 = recs["map-3d"]["metrics"], recs["frame-2.5d"]["metrics"]
    assert recs["map-3d"]["status"] == "ok", recs["map-3d"]["error"]
    assert recs["map-3d"]["task"] == "spatial_qa" and recs["map-3d"]["extras"]["parser"] == "semantic"
    assert m3["accuracy"] >= m25["accuracy"]
    assert m3["notfound_rate"] <= m25["notfound_rate"]
    assert m3["parse_rate"] == m25["parse_rate"] and m3["accuracy_parsed"] >= m3["accuracy"]
    dist = [q for q in recs["map-3d"]["extras"]["questions"] if q["type"] == "howFar" and q["parse"] == "exact"]
    assert dist and sum(distance_ok(q["answer"], q["gt"]) for q in dist) >= 0.75 * len(dist)
    frames = {q["frame"] for q in recs["frame-2.5d"]["extras"]["questions"] if q["frame"] is not None}
    assert len(frames) > 1


def test_the_parser_option_reaches_the_jobs_and_is_checked():
    from harness.runner.map_jobs import map_suite_jobs
    from harness.runner.run import RunConfig

    cfg = RunConfig(suites=("spatial",), encoder="oracle", limit=1, agent_kwargs={"parser": "pattern"})
    assert {j.options["parser"] for j in map_suite_jobs("spatial", cfg, "r")} == {"pattern"}
    with pytest.raises(HarnessError, match=r"parser=llm: suite option 'parser': expected a spatial-question parser: semantic or pattern"):
        RunConfig(suites=("spatial",), encoder="oracle", limit=1, agent_kwargs={"parser": "llm"})


def test_library_receptacles_can_be_asked_about():
    from harness.maps.spatial_questions import RECEPTACLES
    from sim_envs.assets.library import catalogue

    cats = catalogue().categories
    assert {"bowl", "box"} <= set(RECEPTACLES) and all(c in cats for c in RECEPTACLES)
    assert all("container" in catalogue().ancestors(c) for c in RECEPTACLES)


def test_v2_apartment_questions_name_library_objects():
    scan = scan_scene(load_shipped_scene("household-v2-300000"), frames=24, width=160, height=120)
    qs = generate_questions(scan, seed=0)
    names = {o.name for o in scan.scene.objects} | {f["name"] for f in scan.graph.get("furniture", [])} | {"table"}
    assert len({q["type"] for q in qs}) >= 6 and all(q["a"] in names and q["b"] in names for q in qs)


def test_assumed_present_objects_are_located_where_the_floor_drops_them():
    """``assume_present`` (default on): a question's noun phrases are taken to be there, so fewer
    end "not found" than when answered as found, and the options reach the record."""
    from harness.runner.map_jobs import map_suite_jobs
    from harness.runner.run import RunConfig

    scene = sorted(p.stem for p in (ROOT / "scenes" / "tabletop-v2").glob("tabletop-v2-*.json"))[0]
    recs = {}
    for assume in (True, False):
        opts = {"frames": 8, "width": 160, "height": 120, "assume_present": assume, "name_only_fallback": assume}
        recs[assume] = run_map_job(MapJob(run_id="t", suite="spatial-v2", agent="map-3d", encoder="embedded-v2", scene_id=scene, options=opts))[0]
        assert recs[assume]["status"] == "ok", recs[assume]["error"]
        assert recs[assume]["extras"]["assume_present"] is assume
    on, off = recs[True]["metrics"], recs[False]["metrics"]
    assert off["notfound_rate"] > 0 and on["notfound_rate"] < off["notfound_rate"]
    cfg = RunConfig(suites=("spatial-v2",), limit=1, agent_kwargs={"assume_present": False})
    assert {j.options["assume_present"] for j in map_suite_jobs("spatial-v2", cfg, "r")} == {False}
    with pytest.raises(HarnessError, match=r"assume_present=maybe"):
        RunConfig(suites=("spatial-v2",), limit=1, agent_kwargs={"assume_present": "maybe"})
