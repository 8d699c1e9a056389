"""The matched map-free twins: the same geometry and rules as the map agents, semantics per frame."""

import numpy as np
import pytest

import sim_envs  # noqa: F401
from agents.concept_map import ConceptMapper, MapperConfig
from agents.navigator import MapNavigator, NavigatorConfig
from agents.registry import make_agent
from agents.spec import AGENTS, AgentSpec
from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.perception.featurizer import OracleFeaturizer


@pytest.fixture(scope="module")
def scan(tabletop_scan):
    return tabletop_scan(3, 6)


def _mapper(info, **config):
    m = ConceptMapper(OracleFeaturizer(ColorNameEncoder()), MapperConfig(**config))
    m.reset(dict(enumerate(info["object_names"])))
    return m


def _fused(scan, frames, **config):
    m = _mapper(scan[0][1], **config)
    for obs, info in frames:
        m.integrate(obs, segmentation=info["segmentation"])
    return m


def test_twin_keeps_the_geometry_of_every_frame_and_the_concepts_of_the_last_k(scan):
    fused = _fused(scan, scan)
    twin = _fused(scan, scan, semantic_views=2)
    # the same geometry (PointFusion does not depend on the features), no fused concept vectors
    assert len(twin.map) == len(fused.map)
    np.testing.assert_allclose(twin.map.points, fused.map.points)
    assert not twin.map.has_feature.any() and fused.map.has_feature.any()
    assert len(twin._views) == 2
    # points described by the twin: those near the kept frames' featured points; fewer when it keeps fewer
    every = _fused(scan, scan, semantic_views=len(scan)).described_n
    described = twin.described_n
    assert 0 < described.sum() < every.sum() and not (described & ~every).any()


def test_twin_answers_from_its_best_single_frame_on_the_maps_points(scan):
    info0 = scan[0][1]
    name = next(n for n in info0["object_names"] if [m.split()[0] for m in info0["object_names"]].count(n.split()[0]) == 1)
    twin = _fused(scan, scan, semantic_views=len(scan))
    res = twin.locate(name)
    assert res.found, res.reason
    # regions and scores refer to the map's points (indices, positions), as a fused answer does
    assert res.scores_n.shape == (len(twin.map),)
    best = res.best
    np.testing.assert_allclose(twin.map.points[best.indices_n], best.points_n3)
    lo, hi = np.asarray(next(o["aabb"] for o in info0["scene_graph"]["objects"] if o["name"] == name))
    assert np.linalg.norm(best.median[:2] - (lo[:2] + hi[:2]) / 2) < 0.05
    # the answer is one frame's: no more of the object's points than a single frame shows
    per_frame = []
    for obs, info in scan:
        alone = _fused(scan, [(obs, info)])
        r = alone.locate(name)
        per_frame.append(len(r.best.points_n3) if r.found else 0)
    fused = _fused(scan, scan).locate(name)
    assert 0 < len(best.points_n3) < len(fused.best.points_n3)
    assert max(per_frame) > 0


def test_twin_with_one_view_forgets_what_left_the_view(scan):
    info0 = scan[0][1]
    names = info0["object_names"]
    twin = _fused(scan, scan[:1], semantic_views=1)
    seen_first = {n for n in names if twin.locate(n).found}
    for obs, info in scan[1:]:
        twin.integrate(obs, segmentation=info["segmentation"])
    last = _fused(scan, scan[-1:])
    # after the whole scan, the twin finds exactly what the last frame alone finds
    assert {n for n in names if twin.locate(n).found} == {n for n in names if last.locate(n).found}
    assert seen_first  # it did find things in its first view


def test_semantic_views_is_checked():
    with pytest.raises(ValueError, match="semantic_views: expected an integer >= 0"):
        MapperConfig(semantic_views=-1)
    with pytest.raises(ValueError, match="semantic_views"):
        MapperConfig(semantic_views=True)


def test_registered_twins_match_their_map_agents():
    for twin, of in (("twin-navigator", "map-navigator"), ("twin-pusher", "map-pusher")):
        spec, base = AGENTS[twin], AGENTS[of]
        assert spec.twin_of == of and not spec.uses_map and base.uses_map and not spec.privileged
        assert spec.task == base.task
        # tuned alike: every option of the map agent, with the same default (the pusher twin always
        # reads the scan: seeing the same views is what makes it the twin)
        for key, opt in base.kwargs.items():
            if key == "scan":
                continue
            assert key in spec.kwargs and spec.kwargs[key].default == opt.default, key
    nav = make_agent("twin-navigator", encoder="color")
    assert nav.mapper.config.semantic_views == 1 and nav.config.hold_sighting
    assert nav.config.look_again
    assert make_agent("map-navigator", encoder="color").config == NavigatorConfig(
        **{**nav.config.__dict__, "hold_sighting": False, "look_again": False})
    push = make_agent("twin-pusher", encoder="color")
    assert push.use_scan and push.mapper.config.semantic_views >= 9
    with pytest.raises(ValueError, match="a matched twin .* is map-free"):
        AgentSpec("x", lambda: None, "any", "", twin_of="map-pusher", uses_map=True)


class _Mapper:
    """A mapper stand-in for the navigator: an empty room whose frames never show the goal."""

    privileged = False

    def __init__(self):
        ys, xs = np.mgrid[-2:2:0.05, -2:2:0.05]
        floor = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
        wall = np.stack([np.full(200, 2.0), np.linspace(-2, 2, 200), np.full(200, 0.5)], axis=1)
        self.map = type("M", (), {"points": np.concatenate([floor, wall])})()

    def locate(self, text):
        from conceptfusion.map.query import QueryResult

        return QueryResult(False, [], np.zeros(0), np.zeros(0), np.zeros(0), reason="not in view")

    locate_present = locate


@pytest.mark.parametrize("hold", [True, False])
def test_held_sighting_keeps_the_goal_once_it_leaves_the_view(hold):
    nav = MapNavigator(_Mapper(), NavigatorConfig(hold_sighting=hold, presume_after=0))
    nav._goal = "the red mug"
    nav._seen = np.array([[1.5, 1.5], [1.6, 1.5], [1.5, 1.6]])  # where an earlier frame showed it
    nav._plan(np.array([-1.5, -1.5, 0.0]))
    text = "\n".join(nav.log)
    if hold:
        assert "heading for where it was last seen" in text and nav._to_goal and "goal path" in text
    else:
        assert "heading for where it was last seen" not in text and not nav._to_goal
