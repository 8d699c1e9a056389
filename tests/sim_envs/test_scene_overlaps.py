"""The indexed overlap check (sim_envs/scenes/overlaps.py) finds exactly the pairs the pairwise
one finds, and the scene loader still refuses the first overlapping pair, as before."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conceptfusion.errors import SceneFormatError
from sim_envs.scenes.format import SceneObject, scene_from_json
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.overlaps import overlapping_pairs, overlapping_pairs_naive


def _random_objects(rng: np.random.Generator, n: int, extent: float) -> list[SceneObject]:
    """``n`` boxes in a square of side ``extent``: mixed sizes and yaws, three supports (None
    among them), two levels, some exact duplicates and some boxes touching within the tolerance."""
    objs = []
    for k in range(n):
        if k and rng.random() < 0.05:  # an exact copy of an earlier box
            o = objs[int(rng.integers(k))]
            objs.append(SceneObject(f"o{k}", "x", "box", "box", "red", o.position, o.yaw, o.size, (), o.support))
            continue
        x, y = rng.uniform(0, extent, 2)
        z = float(rng.choice([0.0, 0.0, 0.03, 0.4]))
        size = tuple(float(s) for s in rng.uniform(0.02, 0.3, 3))
        yaw = float(rng.choice([0.0, rng.uniform(-np.pi, np.pi)]))
        support = [None, "floor", "f0"][int(rng.integers(3))]
        objs.append(SceneObject(f"o{k}", "x", "box", "box", "red", (float(x), float(y), z), yaw, size, (), support))
    return objs


@pytest.mark.parametrize("seed", range(8))
def test_indexed_check_finds_exactly_the_naive_pairs(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 250))
    objs = _random_objects(rng, n, extent=float(rng.choice([0.5, 2.0, 6.0])))
    for tol in (0.002, 0.0, 0.05, -0.01):
        naive = overlapping_pairs_naive(objs, tol)
        assert overlapping_pairs(objs, tol) == naive
    assert naive or n < 20  # dense scenes do overlap: the comparison is not vacuous


def test_touching_boxes_on_a_line_and_in_a_column():
    # boxes 0.1 wide every 0.1 m along x (touching: not overlapping), then every 0.05 m (overlapping)
    line = [SceneObject(f"a{k}", "x", "box", "box", "red", (0.1 * k, 0.0, 0.0), 0.0, (0.1, 0.1, 0.1)) for k in range(50)]
    assert overlapping_pairs(line) == overlapping_pairs_naive(line) == []
    dense = [SceneObject(f"b{k}", "x", "box", "box", "red", (0.0, 0.05 * k, 0.0), 0.0, (0.1, 0.1, 0.1)) for k in range(50)]
    assert overlapping_pairs(dense) == [(k, k + 1) for k in range(49)]


def test_loader_names_the_first_overlapping_pair_and_counts_the_rest():
    doc = json.loads(json.dumps(generate_tabletop(3).to_json()))
    objs = doc["objects"]
    objs[2]["position"] = list(objs[0]["position"])
    objs[3]["position"] = list(objs[1]["position"])
    with pytest.raises(SceneFormatError, match=r"scene: objects 'obj0' \(.*\) and 'obj2' \(.*\) overlap \(1 more overlapping pair\(s\)\)"):
        scene_from_json(doc)
