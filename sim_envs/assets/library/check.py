"""Check every library instance: it builds, exports, fits its category's size range, and
compiles in MuJoCo; print the catalogue's numbers.

Usage::

    python -m sim_envs.assets.library.check            # uses the asset cache
    python -m sim_envs.assets.library.check --fresh    # builds into an empty temporary cache (timing)
    python -m sim_envs.assets.library.check --pybullet # also loads every instance in PyBullet
"""

from __future__ import annotations

import argparse
import collections
import os
import tempfile
import time

from sim_envs.assets.library.catalogue import Instance, catalogue, catalogue_hash
from sim_envs.assets.library.export import export_instance

__all__ = ["check_instance", "main"]


def check_instance(inst: Instance) -> list[str]:
    """Problems of one instance (empty when fine): export, size range, collision pieces."""
    problems = []
    exp = export_instance(inst)
    lo, hi = catalogue().categories[inst.category].size_range
    longest = max(exp.size)
    if not lo * 0.999 <= longest <= hi * 1.001:
        problems.append(f"longest side {longest:.4f} m outside {lo}-{hi} m")
    if not exp.hulls:
        problems.append("no collision pieces")
    text = exp.visual.read_text()
    if text.count("\nf ") == 0:
        problems.append(f"{exp.visual}: no triangles")
    return problems


def _mujoco_compiles(inst: Instance) -> str | None:
    import mujoco

    from sim_envs.assets.library.mjcf import library_asset_xml, library_geoms

    xml = f"<mujoco><asset>{library_asset_xml([inst.id])}</asset><worldbody><body><freejoint/>{library_geoms(inst.id)}</body></worldbody></mujoco>"
    try:
        mujoco.MjModel.from_xml_string(xml)
    except Exception as exc:  # report, do not stop
        return f"MuJoCo: {exc}"
    return None


def main(argv: list[str] | None = None) -> int:
    """Run the checks; exit status 1 if any instance fails."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fresh", action="store_true", help="build into an empty temporary cache")
    ap.add_argument("--pybullet", action="store_true", help="also load every instance in PyBullet")
    args = ap.parse_args(argv)
    if args.fresh:
        os.environ["CF_ASSET_CACHE"] = tempfile.mkdtemp(prefix="cf-library-")
    cat = catalogue()
    t0 = time.perf_counter()
    failures: dict[str, list[str]] = {}
    for inst in cat.instances.values():
        try:
            probs = check_instance(inst)
        except Exception as exc:  # noqa: BLE001 - report every failure, then fail
            probs = [f"{type(exc).__name__}: {exc}"]
        if probs:
            failures[inst.id] = probs
    t_build = time.perf_counter() - t0
    t1 = time.perf_counter()
    for inst in cat.instances.values():
        msg = _mujoco_compiles(inst)
        if msg:
            failures.setdefault(inst.id, []).append(msg)
    t_mj = time.perf_counter() - t1
    if args.pybullet:
        import pybullet as p

        from sim_envs.assets.library.urdf import load_instance

        client = p.connect(p.DIRECT)
        for k, inst in enumerate(cat.instances.values()):
            try:
                load_instance(inst.id, client, (k % 30 * 1.0, k // 30 * 1.0, 0.0))
            except Exception as exc:  # noqa: BLE001
                failures.setdefault(inst.id, []).append(f"PyBullet: {exc}")
        p.disconnect(client)
    by_source = collections.Counter(i.source for i in cat.instances.values())
    by_licence = collections.Counter(i.licence for i in cat.instances.values())
    print(f"categories: {len(cat.categories)} (+{len(cat.groups)} groups); instances: {len(cat.instances)}")
    print(f"shape variants used: {len({i.variant for i in cat.instances.values()})}")
    print("by source:", dict(by_source))
    print("by licence:", dict(by_licence))
    print(f"catalogue hash: {catalogue_hash()}")
    print(f"export (build + write, {'fresh' if args.fresh else 'cached'}): {t_build:.1f} s; MuJoCo compile: {t_mj:.1f} s")
    for iid, probs in failures.items():
        print(f"FAIL {iid}: {'; '.join(probs)}")
    print("all instances pass" if not failures else f"{len(failures)} instances fail")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
