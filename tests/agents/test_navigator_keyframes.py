"""The navigator's keyframe option: off by default (every frame fused), else only frames from a
new enough viewpoint."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.navigator import MapNavigator, NavigatorConfig


class _CountingMapper:
    """Stands in for the ConceptMapper while the navigator looks around (no query, no plan)."""

    privileged = False

    def __init__(self) -> None:
        self.fused: list[float] = []

    def reset(self, names=None) -> None:
        self.fused.clear()

    def integrate(self, observation, segmentation=None) -> None:
        self.fused.append(float(observation["base_pose"][2]))


def _look_around(config: NavigatorConfig, steps: int = 20, turn_deg: float = 10.0, move: float = 0.0) -> list[float]:
    mapper = _CountingMapper()
    agent = MapNavigator(mapper, config)
    for k in range(steps):
        pose = np.array([move * k, 0.0, math.remainder(math.radians(turn_deg * k), 2 * math.pi)])
        action = agent.act({"base_pose": pose, "goal": "the red mug"})
        assert action[2] == 0.0  # still looking around: no stop
    return mapper.fused


def test_every_frame_is_fused_by_default():
    assert len(_look_around(NavigatorConfig())) == 20


def test_turn_keyframes_fuse_every_third_frame_at_ten_degrees_a_step():
    fused = _look_around(NavigatorConfig(keyframe_turn_deg=25.0))
    assert len(fused) == 7  # steps 0, 3, 6, ..., 18
    assert np.allclose(np.degrees(np.diff(fused)), 30.0)


def test_move_keyframes_fuse_when_the_base_has_moved_far_enough():
    assert len(_look_around(NavigatorConfig(keyframe_move=0.3), turn_deg=1.0, move=0.1)) == 7
    assert len(_look_around(NavigatorConfig(keyframe_move=0.3), turn_deg=1.0, move=0.0)) == 1


@pytest.mark.parametrize("kwargs", [{"keyframe_move": -0.1}, {"keyframe_turn_deg": float("nan")}, {"keyframe_move": "far"}])
def test_bad_keyframe_settings(kwargs):
    with pytest.raises(ValueError, match="expected a finite number >= 0"):
        NavigatorConfig(**kwargs)
