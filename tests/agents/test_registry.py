"""Agents by name: specs, typed options, user import paths, errors."""

import numpy as np
import pytest

from agents.registry import AGENTS, agent_names, make_agent, spec_summary


def test_builtin_agents_are_registered_per_task():
    make_agent("random-walker")  # loads the built-in registrations
    assert {"map-pusher", "frame-pusher", "random-pusher", "oracle-pusher"} <= set(agent_names("tabletop_rearrange"))
    assert {"map-navigator", "frame-searcher", "random-walker"} <= set(agent_names("object_search"))
    assert AGENTS["map-navigator"].uses_map and not AGENTS["frame-searcher"].uses_map
    assert AGENTS["oracle-pusher"].privileged
    s = spec_summary(AGENTS["random-walker"])
    assert s["kwargs"]["p_stop"] == {"type": "float", "default": 0.01}


def test_options_are_converted_from_strings_and_checked():
    a = make_agent("random-walker", seed="3", p_stop="0.5")
    assert a.p_stop == 0.5 and a.seed == 3 and a.privileged is False
    with pytest.raises(ValueError, match="unknown option 'p_stp'.*did you mean 'p_stop'"):
        make_agent("random-walker", p_stp=0.1)
    with pytest.raises(ValueError, match="expected int"):
        make_agent("random-walker", seed="three")


def test_unknown_names_suggest_the_nearest():
    with pytest.raises(ValueError, match="did you mean 'map-navigator'"):
        make_agent("map-navigatr")


def test_user_agents_by_import_path():
    a = make_agent("agents.baselines:RandomPusher", seed=1)
    act = a.act({})
    assert act.shape == (5,)
    with pytest.raises(ValueError, match="has no attribute"):
        make_agent("agents.baselines:Nope")
    with pytest.raises(ValueError, match="cannot import"):
        make_agent("no_such_module_xyz:Agent")


def test_oracle_mapped_agents_are_privileged():
    nav = make_agent("map-navigator", encoder="oracle")
    assert nav.privileged
    walker = make_agent("random-walker", seed=0)
    acts = np.array([walker.act({}) for _ in range(50)])
    assert acts.shape == (50, 3) and np.all(acts[:, 0] >= 0)
