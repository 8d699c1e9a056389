"""Reading push instructions: every shipped instruction gives its episode's targets and sides,
"and" inside a description stays in it."""

from __future__ import annotations

import pytest

from agents.pusher import parse_push_instruction
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes


@pytest.mark.parametrize("text, expected", [
    ("push the red mug to the right of the line and the blue can to the left of the line", [("red mug", "right"), ("blue can", "left")]),
    ("push something to brew and pour tea to the left of the line", [("something to brew and pour tea", "left")]),
    ("push a toy for children to play with to the left of the line and something to sprinkle salt on food to the right of the line",
     [("a toy for children to play with", "left"), ("something to sprinkle salt on food", "right")]),
    ("Push the salt and pepper shaker to the right side.", [("salt and pepper shaker", "right")]),
])
def test_targets_and_sides(text, expected):
    assert parse_push_instruction(text) == expected


@pytest.mark.parametrize("text", ["push the mug", "push the mug to the left of the line and", "", "push to the left"])
def test_unreadable_instructions_are_refused(text):
    with pytest.raises(ValueError, match="instruction"):
        parse_push_instruction(text)


@pytest.mark.parametrize("path", ["tabletop/episodes-v1.jsonl", "tabletop-v2/episodes-v2.jsonl"])
def test_every_shipped_instruction_gives_its_goals(path):
    for ep in load_episodes(SCENES_ROOT / path).episodes:
        targets = parse_push_instruction(ep.instruction)
        assert [side for _, side in targets] == [g.side for g in ep.goals], ep.instruction
        for (name, _), goal in zip(targets, ep.goals):
            if goal.description:
                assert name == goal.description.removeprefix("the "), ep.instruction
