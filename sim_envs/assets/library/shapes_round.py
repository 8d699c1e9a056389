"""Shape variants made mostly of revolved profiles: cups, mugs, bowls, plates, vases, bottles,
jars, glasses, pots, pans, lamps, fruit, balls ...

Every builder takes its parameters (a dict, ranges in :data:`ROUND_SHAPES`) and returns
:class:`~sim_envs.assets.library.geometry.Part` s in arbitrary units, z up; the instance scale
fixes the size later. A profile is given as control points ``(z fraction, r fraction)`` through
which a monotone cubic (PCHIP) runs, so a handful of numbers make a smooth outline.
"""

from __future__ import annotations

import math

import numpy as np

from sim_envs.assets.library.geometry import (
    MeshData, Part, box, cylinder, ellipsoid, revolve, rotation, transform, tube_arc,
)

__all__ = ["ROUND_SHAPES", "lathe", "vessel"]


def _curve(ctrl, n: int = 24) -> tuple[np.ndarray, np.ndarray]:
    from scipy.interpolate import PchipInterpolator

    z, r = np.asarray(ctrl, np.float64).T
    zs = np.linspace(z[0], z[-1], n)
    return zs, np.maximum(PchipInterpolator(z, r)(zs), 1e-3)


def lathe(ctrl, height: float, radius: float, z0: float = 0.0, segments: int = 32) -> MeshData:
    """A closed solid of revolution through control points ``(z fraction, r fraction)``."""
    zs, rs = _curve(ctrl)
    prof = [(0.0, z0)] + [(radius * r, z0 + height * z) for z, r in zip(zs, rs)] + [(0.0, z0 + height * zs[-1])]
    return revolve(prof, segments)


def vessel(ctrl, height: float, radius: float, wall: float, floor: float, z0: float = 0.0, segments: int = 32) -> Part:
    """An open thin-walled vessel whose outside follows ``ctrl``; ``wall`` and ``floor`` are
    thicknesses in the same units as ``height``."""
    zs, rs = _curve(ctrl)
    outer = [(radius * r, z0 + height * z) for z, r in zip(zs, rs)]
    inner = [(max(r - wall, 1e-3), z) for r, z in outer[::-1] if z >= z0 + floor]
    prof = [(0.0, z0)] + outer + inner + [(0.0, z0 + floor)]
    return Part(revolve(prof, segments), "hollow", floor=floor)


def _handle(x: float, z: float, size: float, tube: float) -> Part:
    """A D-shaped side handle at ``x`` (on the +x side), centred at height ``z``."""
    return Part(transform(tube_arc(size, tube, -math.pi / 2, math.pi / 2), None, (x, 0.0, z)))


def _cup(p):
    h = p["aspect"]
    return [vessel([(0, p["taper"]), (1, 1.0)], h, 0.5, p["wall"] * 0.5, 0.06 * h)]


def _mug(p):
    h = p["aspect"]
    body = vessel([(0, p["taper"]), (0.5, (1 + p["taper"]) / 2 + p["belly"]), (1, 1.0)], h, 0.5, 0.04, 0.06 * h)
    return [body, _handle(0.47, h * 0.52, h * p["handle"], 0.045)]


def _bowl(p):
    t = np.linspace(0, 1, 7)
    b = p["base"]
    ctrl = [(1 - math.cos(x * math.pi / 2), b + (1 - b) * math.sin(x * math.pi / 2) ** p["curve"]) for x in t]
    parts = [vessel(ctrl, p["depth"], 0.5, 0.025, 0.04 * p["depth"] + 0.01)]
    if p["foot"] > 0.5:
        parts = [Part(cylinder(0.5 * b * 0.9, 0.05), "hull"), vessel(ctrl, p["depth"], 0.5, 0.025, 0.05, z0=0.04)]
    return parts


def _plate(p):
    h = p["depth"]
    ctrl = [(0, p["flat"]), (0.4, p["flat"] + 0.05), (0.8, 0.9), (1.0, 1.0)]
    return [vessel(ctrl, h, 0.5, 0.012, 0.012)]


def _vase(p):
    ctrl = [(0, p["r0"]), (0.3, p["r1"]), (0.65, p["r2"]), (0.88, p["neck"]), (1.0, p["lip"])]
    return [vessel(ctrl, p["aspect"], 0.5, 0.03, 0.04)]


def _bottle(p):
    h, s = p["aspect"], p["shoulder"]
    ctrl = [(0, 0.95), (0.05, 1.0), (s, 1.0), (s + (0.9 - s) * 0.6, p["neck"] * 1.4), (0.9, p["neck"]), (1.0, p["neck"])]
    cap = cylinder(0.5 * p["neck"] * 1.15, 0.08 * h, z0=0.97 * h, segments=20)
    return [Part(lathe(ctrl, h, 0.5)), Part(cap)]


def _jar(p):
    h = p["aspect"]
    body = lathe([(0, 0.9), (0.1, 1.0), (0.8, 1.0), (0.9, p["neck"]), (1.0, p["neck"])], h, 0.5)
    lid = cylinder(0.5 * p["neck"] * 1.08, 0.12 * h, z0=0.95 * h)
    return [Part(body), Part(lid)]


def _goblet(p):
    stem = p["stem"]
    foot = cylinder(0.32, 0.03, segments=28)
    rod = cylinder(0.035, stem, z0=0.03, segments=12)
    ctrl = [(0, 0.15), (0.35, p["belly"]), (1.0, p["mouth"])]
    bowl = vessel(ctrl, p["bowl"], 0.5, 0.02, 0.05, z0=0.03 + stem * 0.95)
    return [Part(foot), Part(rod), bowl]


def _pot(p):
    h = p["aspect"]
    body = vessel([(0, 0.97), (0.1, 1.0), (1.0, 1.0)], h, 0.5, 0.025, 0.05)
    parts = [body, _handle(0.48, h * 0.8, 0.09, 0.03), Part(transform(_handle(0.48, h * 0.8, 0.09, 0.03).mesh, rotation("z", math.pi)))]
    if p["lid"] > 0.5:
        parts.append(Part(lathe([(0, 1.02), (0.5, 0.9), (1.0, 0.15)], 0.12, 0.5, z0=h)))
        parts.append(Part(cylinder(0.06, 0.06, z0=h + 0.1)))
    return parts


def _pan(p):
    h = p["depth"]
    body = vessel([(0, p["base"]), (1.0, 1.0)], h, 0.5, 0.02, 0.03)
    handle = box((p["handle"], 0.07, 0.035), (0.5 + p["handle"] / 2 - 0.02, 0, h * 0.8), rotation("y", -0.12))
    return [body, Part(handle)]


def _lamp(p):
    base = cylinder(p["base"], 0.05, segments=28)
    stem = cylinder(0.025, p["stem"], z0=0.05, segments=12)
    z = 0.05 + p["stem"]
    rb, rt, sh = p["shade_bottom"], p["shade_top"], p["shade_h"]
    w = 0.015
    ring = [(rb, z - sh * 0.5), (rt, z + sh * 0.5), (rt - w, z + sh * 0.5), (rb - w, z - sh * 0.5), (rb, z - sh * 0.5)]
    return [Part(base), Part(stem), Part(revolve(ring, 32))]


def _dome_lamp(p):
    base = cylinder(p["base"], 0.05, segments=28)
    stem = cylinder(0.025, p["stem"], z0=0.05, segments=12)
    z = 0.05 + p["stem"]
    r = p["shade"]
    t = np.linspace(0, math.pi / 2, 9)
    outer = [(r * math.cos(a), z + r * 0.8 * math.sin(a)) for a in t]
    inner = [(max(x - 0.02, 1e-3), y - 0.02) for x, y in outer[::-1]]
    shade = revolve(outer + inner + [outer[0]], 32)
    return [Part(base), Part(stem), Part(shade)]


def _can(p):
    h = p["aspect"]
    return [Part(lathe([(0, 0.9), (0.04, 1.0), (0.92, 1.0), (1.0, p["top"])], h, 0.5))]


def _bucket(p):
    h = p["aspect"]
    body = vessel([(0, p["taper"]), (1.0, 1.0)], h, 0.5, 0.02, 0.03)
    bail = transform(tube_arc(0.5, 0.012, 0.0, math.pi, 20, 6), None, (0, 0, h * 0.92))
    return [body, Part(bail, "none")]


def _flowerpot(p):
    h = p["aspect"]
    body = vessel([(0, p["taper"]), (0.82, 0.97), (0.84, 1.05), (1.0, 1.05)], h, 0.5, 0.04, 0.08)
    soil = cylinder(0.5 * 0.96, 0.02, z0=h * 0.8)
    return [body, Part(soil, "none")]


def _candle(p):
    h = p["aspect"]
    parts = [Part(cylinder(0.5, h, segments=28, r_top=0.5 * p["taper"])), Part(cylinder(0.02, 0.08, z0=h, segments=6), "none")]
    if p["holder"] > 0.5:
        parts = [Part(cylinder(0.8, 0.06, segments=28)), *[Part(transform(q.mesh, None, (0, 0, 0.06)), q.collision) for q in parts]]
    return parts


def _ball(p):
    return [Part(ellipsoid(0.5, 0.5, 0.5 * p["squash"], (0, 0, 0.5 * p["squash"]), segments=28, rings=14))]


def _fruit(p):
    rz = 0.5 * p["squash"]
    body = ellipsoid(0.5, 0.5, rz, (0, 0, rz), segments=24, rings=12)
    stem = transform(cylinder(0.025, 0.12, segments=6), rotation("x", 0.3), (0, 0, 2 * rz - 0.03))
    return [Part(body), Part(stem, "none")]


def _pear(p):
    body = lathe([(0, 0.05), (0.08, 0.75), (0.3, 1.0), (0.6, p["waist"]), (0.9, p["waist"] * 0.75), (1.0, 0.05)], p["aspect"], 0.5)
    stem = cylinder(0.02, 0.12, z0=p["aspect"] - 0.02, segments=6)
    return [Part(body), Part(stem, "none")]


def _oval(p):
    ln = p["length"]
    body = lathe([(0, 0.02), (0.08, 0.55), (0.3, 0.95), (0.5, 1.0), (0.7, 0.95), (0.92, 0.55), (1.0, p["tip"])], ln, 0.5)
    return [Part(transform(body, rotation("y", math.pi / 2), (-ln / 2, 0, 0.5)))]


def _donut(p):
    tube = 0.5 * p["thickness"]
    ring = tube_arc(0.5 - tube, tube, 0, 2 * math.pi, 32, 14)
    return [Part(transform(ring, rotation("x", math.pi / 2), (0, 0, tube)))]


def _teapot(p):
    h = p["aspect"]
    body = lathe([(0, 0.7), (0.15, 0.95), (0.5, 1.0), (0.85, 0.7), (1.0, 0.35)], h, 0.5)
    spout = transform(cylinder(0.07, 0.45, segments=12, r_top=0.04), rotation("y", 0.8), (0.4, 0, h * 0.3))
    lid = cylinder(0.05, 0.08, z0=h, segments=12)
    parts = [Part(body), Part(spout), Part(lid, "none")]
    if p["top_handle"] > 0.5:
        parts.append(Part(transform(tube_arc(0.3, 0.03, 0.2, math.pi - 0.2, 16, 8), None, (0, 0, h * 0.85))))
    else:
        parts.append(Part(transform(_handle(0.45, h * 0.5, h * 0.3, 0.04).mesh, rotation("z", math.pi))))
    return parts


def _pitcher(p):
    h = p["aspect"]
    body = vessel([(0, 0.85), (0.45, 1.0), (0.85, p["neck"]), (1.0, p["neck"] + 0.08)], h, 0.5, 0.03, 0.05)
    return [body, _handle(0.45, h * 0.55, h * 0.3, 0.045)]


def _shaker(p):
    h = p["aspect"]
    body = lathe([(0, 1.0), (0.7, p["waist"]), (0.8, 1.0), (0.9, 0.95), (1.0, 0.4)], h, 0.5, segments=int(p["sides"]))
    return [Part(body)]


def _cone(p):
    h = p["aspect"]
    base = box((1.0, 1.0, 0.05), (0, 0, 0.025))
    cone = cylinder(0.38, h, z0=0.05, r_top=0.06, segments=28)
    return [Part(base), Part(cone)]


def _top(p):
    h = p["aspect"]
    body = lathe([(0, 0.02), (0.45, 1.0), (0.6, 0.9), (0.62, 0.1), (1.0, 0.08)], h, 0.5, segments=24)
    return [Part(body)]


def _bell(p):
    h = p["aspect"]
    body = lathe([(0, 1.0), (0.1, 0.85), (0.5, 0.55), (0.9, 0.45), (1.0, 0.1)], h, 0.5)
    knob = ellipsoid(0.08, 0.08, 0.08, (0, 0, h + 0.05), segments=12, rings=6)
    return [Part(body), Part(knob)]


def _trophy(p):
    h = p["aspect"]
    base = box((0.55, 0.55, 0.15), (0, 0, 0.075))
    stem = cylinder(0.06, h * 0.3, z0=0.15, segments=12)
    cup = vessel([(0, 0.2), (0.5, 0.8), (1.0, 1.0)], h * 0.55, 0.4, 0.02, 0.05, z0=0.15 + h * 0.28)
    zc = 0.15 + h * 0.6
    left = Part(transform(_handle(0.38, zc, 0.12, 0.025).mesh, rotation("z", math.pi)))
    return [Part(base), Part(stem), cup, _handle(0.38, zc, 0.12, 0.025), left]


def _bulb(p):
    h = p["aspect"]
    glass = lathe([(0, 0.3), (0.3, 0.35), (0.6, 1.0), (0.85, 0.85), (1.0, 0.05)], h, 0.5)
    screw = cylinder(0.16, 0.2 * h, segments=16)
    return [Part(screw), Part(transform(glass, None, (0, 0, 0.15 * h)))]


def _torch(p):
    ln = p["length"]
    body = lathe([(0, 0.6), (0.7, 0.6), (0.8, 1.0), (1.0, 1.0)], ln, 0.5 * p["head"])
    return [Part(transform(body, rotation("y", math.pi / 2), (-ln / 2, 0, 0.5 * p["head"])))]


def _disc(p):
    lip = p["lip"]
    body = lathe([(0, 0.8), (0.3, 0.95), (1.0, 1.0)], lip, 0.5)
    return [Part(body)]


def _hat(p):
    brim = cylinder(0.5, 0.02, segments=32)
    crown = lathe([(0, 1.0), (0.8, 0.95), (1.0, 0.7)], p["crown_h"], 0.5 * p["crown_r"], z0=0.02)
    return [Part(brim), Part(crown)]


def _plant(p):
    h = p["pot_h"]
    pot = vessel([(0, 0.75), (1.0, 1.0)], h, 0.3, 0.03, 0.05)
    leaves = [Part(ellipsoid(0.32, 0.32, p["foliage"], (0, 0, h + p["foliage"] * 0.8), segments=16, rings=8))]
    if p["tall"] > 0.5:
        leaves.append(Part(ellipsoid(0.22, 0.22, p["foliage"], (0.05, 0, h + p["foliage"] * 2.0), segments=16, rings=8)))
    return [pot, *leaves]


def _rolling_pin(p):
    ln = p["length"]
    drum = cylinder(0.5 * p["thick"], ln * 0.65, z0=-ln * 0.325, segments=20)
    handles = cylinder(0.5 * p["thick"] * 0.45, ln, z0=-ln / 2, segments=12)
    rot = rotation("y", math.pi / 2)
    return [Part(transform(drum, rot, (0, 0, 0.5 * p["thick"]))), Part(transform(handles, rot, (0, 0, 0.5 * p["thick"])))]


def _battery(p):
    h = p["aspect"]
    return [Part(cylinder(0.5, h, segments=20)), Part(cylinder(0.18, 0.05 * h, z0=h, segments=12))]


def _pedestal_bowl(p):
    t = np.linspace(0, 1, 6)
    ctrl = [(1 - math.cos(x * math.pi / 2), 0.3 + 0.7 * math.sin(x * math.pi / 2)) for x in t]
    foot = cylinder(0.3, 0.04, segments=24)
    stem = cylinder(0.08, p["stem"], z0=0.04, segments=16)
    return [Part(foot), Part(stem), vessel(ctrl, p["depth"], 0.5, 0.02, 0.04, z0=0.04 + p["stem"])]


# name: (builder, {param: (lo, hi)})
ROUND_SHAPES: dict[str, tuple] = {
    "cup_straight": (_cup, {"aspect": (0.9, 1.3), "taper": (0.85, 1.0), "wall": (0.05, 0.08)}),
    "cup_tapered": (_cup, {"aspect": (0.9, 1.5), "taper": (0.6, 0.8), "wall": (0.04, 0.07)}),
    "mug_round": (_mug, {"aspect": (0.8, 1.1), "taper": (0.9, 1.0), "belly": (0.0, 0.08), "handle": (0.22, 0.3)}),
    "mug_tall": (_mug, {"aspect": (1.15, 1.6), "taper": (0.8, 0.95), "belly": (-0.05, 0.0), "handle": (0.18, 0.26)}),
    "bowl_round": (_bowl, {"depth": (0.35, 0.5), "base": (0.3, 0.5), "curve": (0.7, 1.2), "foot": (0.0, 0.0)}),
    "bowl_flared": (_bowl, {"depth": (0.25, 0.4), "base": (0.35, 0.5), "curve": (1.5, 2.5), "foot": (1.0, 1.0)}),
    "bowl_pedestal": (_pedestal_bowl, {"depth": (0.3, 0.45), "stem": (0.08, 0.2)}),
    "plate_flat": (_plate, {"depth": (0.05, 0.08), "flat": (0.55, 0.7)}),
    "plate_deep": (_plate, {"depth": (0.1, 0.16), "flat": (0.4, 0.55)}),
    "vase_bulb": (_vase, {"aspect": (1.1, 1.6), "r0": (0.5, 0.6), "r1": (0.9, 1.0), "r2": (0.6, 0.8), "neck": (0.3, 0.4), "lip": (0.45, 0.6)}),
    "vase_slender": (_vase, {"aspect": (2.0, 3.0), "r0": (0.7, 0.8), "r1": (0.75, 0.85), "r2": (0.8, 0.9), "neck": (0.85, 0.95), "lip": (0.95, 1.0)}),
    "vase_amphora": (_vase, {"aspect": (1.5, 2.0), "r0": (0.35, 0.45), "r1": (0.8, 0.9), "r2": (0.95, 1.0), "neck": (0.35, 0.45), "lip": (0.6, 0.75)}),
    "bottle_round": (_bottle, {"aspect": (2.6, 3.4), "shoulder": (0.45, 0.6), "neck": (0.28, 0.36)}),
    "bottle_wine": (_bottle, {"aspect": (3.6, 4.4), "shoulder": (0.55, 0.65), "neck": (0.22, 0.28)}),
    "bottle_squat": (_bottle, {"aspect": (1.6, 2.2), "shoulder": (0.35, 0.5), "neck": (0.35, 0.45)}),
    "jar_wide": (_jar, {"aspect": (0.8, 1.1), "neck": (0.85, 0.95)}),
    "jar_tall": (_jar, {"aspect": (1.3, 1.8), "neck": (0.7, 0.85)}),
    "goblet_round": (_goblet, {"stem": (0.35, 0.55), "bowl": (0.45, 0.6), "belly": (0.9, 1.0), "mouth": (0.75, 0.85)}),
    "goblet_flute": (_goblet, {"stem": (0.4, 0.6), "bowl": (0.7, 0.9), "belly": (0.6, 0.7), "mouth": (0.55, 0.65)}),
    "pot_handles": (_pot, {"aspect": (0.55, 0.85), "lid": (0.0, 1.0)}),
    "saucepan": (_pan, {"depth": (0.4, 0.6), "base": (0.95, 1.0), "handle": (0.7, 0.9)}),
    "frying_pan": (_pan, {"depth": (0.1, 0.16), "base": (0.75, 0.85), "handle": (0.8, 1.0)}),
    "lamp_shade": (_lamp, {"base": (0.2, 0.28), "stem": (0.6, 1.0), "shade_bottom": (0.4, 0.5), "shade_top": (0.25, 0.35), "shade_h": (0.35, 0.5)}),
    "lamp_dome": (_dome_lamp, {"base": (0.2, 0.26), "stem": (0.5, 0.8), "shade": (0.35, 0.45)}),
    "can": (_can, {"aspect": (1.3, 2.2), "top": (0.85, 0.95)}),
    "bucket": (_bucket, {"aspect": (0.8, 1.0), "taper": (0.7, 0.85)}),
    "flowerpot": (_flowerpot, {"aspect": (0.75, 1.0), "taper": (0.6, 0.75)}),
    "candle_pillar": (_candle, {"aspect": (1.0, 2.2), "taper": (1.0, 1.0), "holder": (0.0, 0.0)}),
    "candle_taper": (_candle, {"aspect": (5.0, 8.0), "taper": (0.7, 0.85), "holder": (1.0, 1.0)}),
    "ball": (_ball, {"squash": (1.0, 1.0)}),
    "ball_squashed": (_ball, {"squash": (0.9, 0.97)}),
    "fruit_round": (_fruit, {"squash": (0.82, 0.98)}),
    "fruit_pear": (_pear, {"aspect": (1.3, 1.6), "waist": (0.5, 0.65)}),
    "fruit_oval": (_oval, {"length": (1.3, 1.6), "tip": (0.08, 0.15)}),
    "donut": (_donut, {"thickness": (0.32, 0.42)}),
    "teapot": (_teapot, {"aspect": (0.7, 0.95), "top_handle": (0.0, 0.0)}),
    "kettle": (_teapot, {"aspect": (0.9, 1.2), "top_handle": (1.0, 1.0)}),
    "pitcher": (_pitcher, {"aspect": (1.3, 1.8), "neck": (0.75, 0.9)}),
    "shaker_round": (_shaker, {"aspect": (1.6, 2.4), "waist": (0.85, 1.0), "sides": (24, 24)}),
    "shaker_hex": (_shaker, {"aspect": (1.8, 2.6), "waist": (0.9, 1.0), "sides": (6, 6)}),
    "mill": (_shaker, {"aspect": (3.0, 4.5), "waist": (0.6, 0.75), "sides": (20, 20)}),
    "traffic_cone": (_cone, {"aspect": (1.1, 1.4)}),
    "spinning_top": (_top, {"aspect": (0.8, 1.1)}),
    "bell": (_bell, {"aspect": (0.8, 1.1)}),
    "trophy": (_trophy, {"aspect": (1.2, 1.7)}),
    "light_bulb": (_bulb, {"aspect": (1.5, 1.8)}),
    "flashlight": (_torch, {"length": (3.0, 4.5), "head": (1.0, 1.0)}),
    "disc": (_disc, {"lip": (0.08, 0.14)}),
    "hat": (_hat, {"crown_h": (0.25, 0.4), "crown_r": (0.55, 0.65)}),
    "plant_bush": (_plant, {"pot_h": (0.35, 0.5), "foliage": (0.25, 0.35), "tall": (0.0, 0.0)}),
    "plant_tall": (_plant, {"pot_h": (0.3, 0.4), "foliage": (0.22, 0.3), "tall": (1.0, 1.0)}),
    "rolling_pin": (_rolling_pin, {"length": (5.0, 7.0), "thick": (1.0, 1.0)}),
    "battery": (_battery, {"aspect": (1.8, 3.6)}),
}
"""Revolved shape variants: name -> (builder, parameter ranges)."""
