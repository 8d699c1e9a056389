"""The navigator's keyframe rule: only frames from a new enough viewpoint are fused (0.3 m or 40
degrees by default); 0 and 0 fuse every frame."""

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


def test_every_frame_is_fused_with_the_rule_off():
    assert len(_look_around(NavigatorConfig(keyframe_move=0.0, keyframe_turn_deg=0.0))) == 20


def test_default_rule_fuses_a_frame_every_forty_degrees_or_thirty_centimetres():
    assert (NavigatorConfig().keyframe_move, NavigatorConfig().keyframe_turn_deg) == (0.3, 40.0)
    fused = _look_around(NavigatorConfig(), steps=16, turn_deg=21.0)
    assert len(fused) == 8  # steps 0, 2, 4, ..., 14 at 21 degrees a step
    assert np.allclose(np.degrees(np.diff(np.unwrap(fused))), 42.0)
    assert len(_look_around(NavigatorConfig(), turn_deg=1.0, move=0.1)) == 7  # every 3rd step: 0.3 m


def test_the_builtin_agents_defaults_are_the_configs():
    import inspect

    from agents.registry import AGENTS

    spec = AGENTS["map-navigator"]
    factory_defaults = inspect.signature(spec.factory).parameters
    for name in ("keyframe_move", "keyframe_turn_deg"):
        # the registered option, the factory's keyword and the config dataclass: one value
        assert spec.kwargs[name].default == factory_defaults[name].default == getattr(NavigatorConfig(), name)


def test_turn_keyframes_fuse_every_third_frame_at_ten_degrees_a_step():
    fused = _look_around(NavigatorConfig(keyframe_move=0.0, keyframe_turn_deg=25.0))
    assert len(fused) == 7  # steps 0, 3, 6, ..., 18
    assert np.allclose(np.degrees(np.diff(fused)), 30.0)


def test_move_keyframes_fuse_when_the_base_has_moved_far_enough():
    move_only = NavigatorConfig(keyframe_move=0.3, keyframe_turn_deg=0.0)
    assert len(_look_around(move_only, turn_deg=1.0, move=0.1)) == 7
    assert len(_look_around(move_only, turn_deg=1.0, move=0.0)) == 1


@pytest.mark.parametrize("kwargs", [{"keyframe_move": -0.1}, {"keyframe_turn_deg": float("nan")}, {"keyframe_move": "far"}])
def test_bad_keyframe_settings(kwargs):
    with pytest.raises(ValueError, match="expected a finite number >= 0"):
        NavigatorConfig(**kwargs)
