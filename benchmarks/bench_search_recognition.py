"""Why a perceived map navigator misses its goal: how large it sees objects, and where the goal ranks.

    python benchmarks/bench_search_recognition.py [--episodes calibration|validation] [--limit 60] [--at 200]
        [--encoder embedded-v2] [--every 10] [--json OUT.jsonl] [--isolated] [--compare-proposer SPEC ...]

Runs ``map-navigator`` on the development searches of ``search-v2`` (never the test episodes),
exactly as the harness runs it (same environment settings, seeds and agent options), and measures
from the environment's ground truth, which only this script reads, never the agent:

* **ranks**: at step ``--at`` and at the end of each search, for every object of the apartment
  (boxes from the reset's scene graph) the median score, for the goal description, of the map
  points with features inside its box (at least 10 of them, else the object is not in the map);
  the goal's rank among the objects in the map and its point count, for failed and solved searches;
* **proposals**: on every ``--every``-th frame the navigator sees, the search agents' proposer's
  (:data:`~conceptfusion.perception.featurizer.SEARCH_PROPOSER`) recall of the objects in view (a mask with IoU >= 0.5 against the ground-truth segmentation), by the
  object's pixel count, and the goal's pixel count whenever it is in view;
* **other proposals** (``--compare-proposer SPEC``, repeatable): the same recall, on the same
  frames, of other proposer specs (the navigator still acts on its own), to compare settings;
* **isolated** (``--isolated``): beside the navigator's map, a second map fused from the same
  frames in which a pixel keeps its feature only when a mask isolates its object (IoU >= 0.5 with
  the object's ground-truth segment); the goal's rank there too, to tell views that never
  isolated the goal from features averaged over views that did not;
* **names**: for each object so matched, whether the navigator's encoder names the crop of its
  best mask (the tight box the feature pipeline encodes) by its category, top-1 among every
  library category name, by the same pixel counts.
"""

from __future__ import annotations

import argparse
import collections
import json
import statistics
import sys

import numpy as np

_MIN_POINTS = 10
"""Featured map points an object needs inside its box to count as in the map."""

_MATCH_IOU = 0.5
"""IoU with an object's ground-truth segment at which a mask isolates the object."""


def goal_rank(mapper, goal: str, boxes: np.ndarray, goal_index: int) -> dict:
    """The goal's rank (1 = best) among the objects in the map by the median score of their
    points for ``goal``; ``rank`` None when the goal is not in the map.

    Shape:
        boxes: (num_objects, 2, 3) world boxes, lower and upper corners.
    """
    pts = mapper.map.points
    medians, counts = [], []
    scores = mapper.map.scores_many(mapper.text_vector(goal)[None])[0] if len(pts) else np.zeros(0, np.float32)
    for lo, hi in boxes:
        inside = np.all((pts >= lo - 0.02) & (pts <= hi + 0.02), axis=1) if len(pts) else np.zeros(0, bool)
        s = scores[inside]
        s = s[np.isfinite(s)]
        counts.append(int(len(s)))
        medians.append(float(np.median(s)) if len(s) >= _MIN_POINTS else None)
    g = medians[goal_index]
    others = [m for i, m in enumerate(medians) if i != goal_index and m is not None]
    return {"rank": None if g is None else 1 + sum(m > g for m in others),
            "objects_in_map": len(others) + (g is not None), "goal_points": counts[goal_index]}


def isolating_masks(masks, segmentation) -> list[tuple[int, np.ndarray, int | None]]:
    """Per object in view: its id, its ground-truth segment (H, W) bool and the index of the mask
    that isolates it (the best IoU with its segment, when at least ``_MATCH_IOU``; else None).

    Shape:
        masks (R, H, W) bool, segmentation (H, W) int (-1: no object)."""
    out = []
    for oid in np.unique(segmentation[segmentation >= 0]):
        seg = segmentation == oid
        best = None
        if len(masks):
            iou = (masks & seg).sum(axis=(1, 2)) / (masks | seg).sum(axis=(1, 2))
            best = int(np.argmax(iou)) if iou.max() >= _MATCH_IOU else None
        out.append((int(oid), seg, best))
    return out


def _recall(proposer, obs, segmentation, buckets, goal_pixels, goal_index, namer=None, categories=()) -> None:
    """Proposer recall (and, with ``namer``, naming) of the objects in one frame, into ``buckets``:
    log2 pixel count -> [in view, matched by a mask, named right]."""
    from conceptfusion.perception.features import crop_masks

    masks = proposer.propose(obs["rgb"], obs["depth"], obs["K"])
    matched = []
    for oid, seg, best in isolating_masks(masks, segmentation):
        n = int(seg.sum())
        if n < 4:
            continue
        b = buckets[min(int(np.log2(n)), 12)]
        b[0] += 1
        if best is not None:
            b[1] += 1
            matched.append((b, best, categories[oid] if len(categories) else None))
        if oid == goal_index:
            goal_pixels.append(n)
    if namer is None or not matched:
        return
    encoder, names, name_vecs = namer
    crops = crop_masks(obs["rgb"], masks[[k for _, k, _ in matched]])
    emb = np.asarray(encoder.encode_image(crops), np.float32)
    top = np.argmax(emb @ name_vecs.T, axis=1)
    for (b, _, category), k in zip(matched, top):
        b[2] += names[int(k)] == category


def isolated_features(featurizer, obs, segmentation):
    """The frame's pixel-aligned features as ``featurizer`` computes them, kept only on pixels that
    a mask isolates the object of (IoU >= 0.5 with its ground-truth segment); -1 elsewhere."""
    from conceptfusion.perception.features import PixelFeatures
    from conceptfusion.perception.pipeline import frame_features

    masks = featurizer.proposer.propose(obs["rgb"], obs["depth"], obs["K"])
    feats = frame_features(obs["rgb"], masks, featurizer.encoder, uniqueness=featurizer.uniqueness, mode=featurizer.mode)
    keep = np.zeros(segmentation.shape, bool)
    for _, seg, best in isolating_masks(masks, segmentation):
        if best is not None:
            keep |= seg & masks[best]
    return PixelFeatures(feats.palette_pd, np.where(keep, feats.index_hw, -1).astype(np.int32))


def run(episodes: str, limit: int, at: int, encoder: str | None, every: int, out=None, log=print, isolated: bool = False,
        env_kwargs: dict | None = None, compare: tuple[str, ...] = ()) -> dict:
    from agents.registry import make_agent
    from conceptfusion.perception.featurizer import SEARCH_PROPOSER
    from conceptfusion.perception.masks.registry import make_proposer
    from harness.runner.develop import development_suite
    from harness.runner.run import RunConfig, episode_jobs
    from harness.runner.tasks import env_kwargs_for, episode_seed
    from sim_envs.envs.object_search import ObjectSearchEnv

    suite = development_suite("search-v2", env_kwargs, episodes=episodes)
    options = {} if encoder is None else {"encoder": encoder}
    jobs = episode_jobs(suite, RunConfig(suites=("search-v2",), agents=("map-navigator",), agent_kwargs=options,
                                         backend="serial", record="none"), "recognition")[:limit]
    proposer = make_proposer(SEARCH_PROPOSER)
    buckets: dict[int, list[int]] = collections.defaultdict(lambda: [0, 0, 0])
    others = {spec: (make_proposer(spec), collections.defaultdict(lambda: [0, 0, 0])) for spec in compare}
    from sim_envs.assets.library import catalogue

    names = sorted(catalogue().categories)
    goal_pixels: list[int] = []
    rows, env, env_key, namer = [], None, None, None
    for job in jobs:
        agent = make_agent(job.agent, **job.agent_kwargs)
        kwargs = {**env_kwargs_for(job.task, job.env_kwargs, agent), "segmentation": True}
        if env is None or env_key != sorted(kwargs.items()):
            env, env_key = ObjectSearchEnv(**kwargs), sorted(kwargs.items())
        obs, info = env.reset(seed=job.seed, options={"episode": job.episode})
        agent.reset(seed=episode_seed(job))
        boxes = np.array([o["aabb"] for o in info["scene_graph"]["objects"]], np.float64)
        goal_index = [o["id"] for o in info["scene_graph"]["objects"]].index(job.episode.goals[0].object_id)
        goal = str(obs["goal"])
        categories = [o["category"] for o in info["scene_graph"]["objects"]]
        if namer is None:
            name_vecs = np.asarray(agent.mapper.featurizer.encode_text(names), np.float32)
            namer = (agent.mapper.encoder, names, name_vecs)
        snaps, steps = {}, 0
        iso = _isolated_map(agent, info) if isolated else None
        while True:
            if steps % every == 0:
                _recall(proposer, obs, info["segmentation"], buckets, goal_pixels, goal_index, namer, categories)
                for other, other_buckets in others.values():
                    _recall(other, obs, info["segmentation"], other_buckets, [], goal_index)
            obs, _, terminated, truncated, info = env.step(agent.act(obs, None))
            steps += 1
            if iso is not None:
                iso.seg = info["segmentation"]
            if steps == at:
                snaps["at"] = goal_rank(agent.mapper, goal, boxes, goal_index)
                if iso is not None:
                    snaps["isolated_at"] = goal_rank(iso.view, goal, boxes, goal_index)
            if terminated or truncated:
                break
        snaps["end"] = goal_rank(agent.mapper, goal, boxes, goal_index)
        if iso is not None:
            snaps["isolated_end"] = goal_rank(iso.view, goal, boxes, goal_index)
        row = {"episode_id": job.episode.episode_id, "success": bool(info["success"]), "steps": int(info["steps"]), "goal": goal, **snaps}
        rows.append(row)
        if out is not None:
            out.write(json.dumps(row) + "\n")
            out.flush()
        log(f"{row['episode_id']}: success={row['success']} steps={row['steps']} at {at}: {snaps.get('at')} end: {snaps['end']}")
    return {"rows": rows, "buckets": dict(buckets), "goal_pixels": goal_pixels,
            "compare": {spec: dict(b) for spec, (_, b) in others.items()}}


def _isolated_map(agent, info):
    """A second map that every frame the agent fuses also goes into, with :func:`isolated_features`
    (the segmentation of the frame being acted on is set on the returned object as ``seg``)."""
    from types import SimpleNamespace

    from conceptfusion.map.fusion import PointFusionMap

    mapper = agent.mapper
    iso = SimpleNamespace(seg=info["segmentation"], map=PointFusionMap(mapper.featurizer.dim, max_depth=mapper.config.max_depth))
    iso.view = SimpleNamespace(map=iso.map, text_vector=mapper.text_vector)
    fuse = mapper.integrate

    def integrate(observation, *, segmentation=None):
        fuse(observation, segmentation=segmentation)
        feats = isolated_features(mapper.featurizer, observation, iso.seg)
        iso.map.integrate(observation["rgb"], np.asarray(observation["depth"], np.float32), observation["K"],
                          observation["cam_to_world"], feats)

    mapper.integrate = integrate
    return iso


def summary(result: dict, at: int) -> list[str]:
    rows = result["rows"]
    lines = [f"{len(rows)} searches, {sum(r['success'] for r in rows)} solved"]
    for solved in (False, True):
        group = [r for r in rows if r["success"] == solved]
        snap = [(r.get("at") if not solved else None) or r["end"] for r in group]
        inmap = [s for s in snap if s["rank"] is not None]
        if not inmap:
            continue
        what = f"failed, at step {at} (or the end)" if not solved else "solved, at the end"
        lines.append(f"{what}: goal in the map in {len(inmap)} of {len(group)}; median points {statistics.median(s['goal_points'] for s in inmap):.0f}; "
                     f"rank 1 in {sum(s['rank'] == 1 for s in inmap)}, median rank {statistics.median(s['rank'] for s in inmap):.0f} "
                     f"of a median {statistics.median(s['objects_in_map'] for s in inmap):.0f} objects")
    if any("isolated_end" in r for r in rows):
        for solved in (False, True):
            group = [r for r in rows if r["success"] == solved]
            pairs = [((r.get("at") if not solved else None) or r["end"], (r.get("isolated_at") if not solved else None) or r["isolated_end"])
                     for r in group]
            both = [(a, b) for a, b in pairs if a["rank"] is not None and b["rank"] is not None]
            lines.append(f"{'failed' if not solved else 'solved'}: goal isolated by a mask in enough views to be in the isolated map "
                         f"in {sum(b['rank'] is not None for _, b in pairs)} of {len(group)}")
            if both:
                lines.append(f"{'failed' if not solved else 'solved'}, goal in both maps in {len(both)}: rank 1 in {sum(a['rank'] == 1 for a, _ in both)} "
                             f"(fused) against {sum(b['rank'] == 1 for _, b in both)} (isolated views only); median rank "
                             f"{statistics.median(a['rank'] for a, _ in both):.0f} against {statistics.median(b['rank'] for _, b in both):.0f}; "
                             f"median points {statistics.median(a['goal_points'] for a, _ in both):.0f} against "
                             f"{statistics.median(b['goal_points'] for _, b in both):.0f}")
    for b in sorted(result["buckets"]):
        n, hit, named = result["buckets"][b]
        lines.append(f"objects of {2 ** b}-{2 ** (b + 1) - 1} pixels: {n} in view, proposer recall@0.5 {hit / n:.2f}"
                     + (f", named right (top-1 of the library's categories) {named}/{hit} = {named / hit:.2f} of those matched" if hit else ""))
    for spec, other in result.get("compare", {}).items():
        lines.append(f"{spec}: proposer recall@0.5 " + ", ".join(
            f"{2 ** b}-{2 ** (b + 1) - 1} px {other[b][1] / other[b][0]:.2f}" for b in sorted(other)))
    if result["goal_pixels"]:
        lines.append(f"goal in view: {len(result['goal_pixels'])} frames, median {statistics.median(result['goal_pixels']):.0f} pixels")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", choices=("calibration", "validation"), default="calibration")
    ap.add_argument("--limit", type=int, default=60, help="first N development searches")
    ap.add_argument("--at", type=int, default=200, help="step of the mid-search snapshot (the presumption step by default)")
    ap.add_argument("--encoder", default=None, help="perception (default: the suite's)")
    ap.add_argument("--every", type=int, default=10, help="proposer recall on every N-th frame")
    ap.add_argument("--json", default=None, help="also write one JSON line per search")
    ap.add_argument("--isolated", action="store_true", help="also fuse a map from isolated objects' pixels only (twice the perception)")
    ap.add_argument("--compare-proposer", action="append", default=[], metavar="SPEC",
                    help="also measure this proposer's recall on the same frames (repeatable)")
    ap.add_argument("--env-option", action="append", metavar="KEY=VALUE",
                    help="one of the suite's environment settings, e.g. width=320 (repeatable)")
    args = ap.parse_args(argv)
    from harness.runner.develop import parse_env_options

    if args.limit < 1 or args.at < 1 or args.every < 1:
        ap.error(f"--limit, --at and --every: expected integers >= 1, got {args.limit}, {args.at}, {args.every}")
    out = open(args.json, "w") if args.json else None
    try:
        result = run(args.episodes, args.limit, args.at, args.encoder, args.every, out, isolated=args.isolated,
                     env_kwargs=parse_env_options(args.env_option), compare=tuple(args.compare_proposer))
    finally:
        if out is not None:
            out.close()
    print("\n".join(summary(result, args.at)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
