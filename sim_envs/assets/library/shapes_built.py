"""Shape variants built from boxes, cylinders and slabs: books, boxes, chairs, stools, shelves,
tables, toys, tools, cutlery, electronics, stationery, linen ...

Builders as in :mod:`~sim_envs.assets.library.shapes_round`: parameters in, parts out, z up,
arbitrary units. Objects that lie down (tools, cutlery, pens) are built along x.
"""

from __future__ import annotations

import math

import numpy as np

from sim_envs.assets.library.geometry import Part, box, cylinder, ellipsoid, rotation, slab, transform, tube_arc

__all__ = ["BUILT_SHAPES"]


def _b(size, center, rot=None, collision="hull") -> Part:
    return Part(box(size, center, rot), collision)


def _rod_x(r: float, length: float, x0: float, z: float, segments: int = 12, r_end: float | None = None) -> Part:
    """A cylinder along +x from ``x0``, axis at height ``z``."""
    return Part(transform(cylinder(r, length, segments=segments, r_top=r_end), rotation("y", math.pi / 2), (x0, 0, z)))


def _rounded_rect(w: float, d: float, r: float, n: int = 6) -> np.ndarray:
    pts = []
    for cx, cy, a0 in ((w / 2 - r, d / 2 - r, 0), (-w / 2 + r, d / 2 - r, 90), (-w / 2 + r, -d / 2 + r, 180), (w / 2 - r, -d / 2 + r, 270)):
        for t in np.radians(np.linspace(a0, a0 + 90, n)):
            pts.append((cx + r * math.cos(t), cy + r * math.sin(t)))
    return np.array(pts)


def _book(p):
    w, d, t = 1.0, p["width"], p["thick"]
    if p["hard"] < 0.5:
        return [_b((d, w, t), (0, 0, t / 2))]
    c = 0.04 * t + 0.01
    return [_b((d, w, c), (0, 0, c / 2)), _b((d, w, c), (0, 0, t - c / 2)),
            _b((d - 0.03, w - 0.04, t - 2 * c), (0.015, 0, t / 2)), _b((0.02, w, t), (-d / 2 + 0.01, 0, t / 2))]


def _box(p):
    w, d, h = 1.0, p["depth"], p["height"]
    parts = [_b((w, d, h), (0, 0, h / 2))]
    if p["lid"] > 0.5:
        lh = 0.15 * h
        parts = [_b((w * 0.97, d * 0.97, h - lh * 0.5), (0, 0, (h - lh * 0.5) / 2)), _b((w, d, lh), (0, 0, h - lh / 2))]
    return parts


def _open_box(p):
    w, d, h, t = 1.0, p["depth"], p["height"], p["wall"]
    parts = [_b((w, d, t), (0, 0, t / 2)), _b((t, d, h), (w / 2 - t / 2, 0, h / 2)), _b((t, d, h), (-w / 2 + t / 2, 0, h / 2)),
             _b((w, t, h), (0, d / 2 - t / 2, h / 2)), _b((w, t, h), (0, -d / 2 + t / 2, h / 2))]
    if p["handle"] > 0.5:
        parts.append(Part(transform(tube_arc(0.45, 0.015, 0.0, math.pi, 16, 6), None, (0, 0, h)), "hull"))
    return parts


def _chair(p):
    s, hs, hb, lt = 1.0, p["seat_h"], p["back_h"], 0.07
    parts = [_b((s, s, 0.08), (0, 0, hs))]
    for x, y in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        top = hs + (hb if y > 0 else 0)
        parts.append(_b((lt, lt, top), (x * (s / 2 - lt / 2), y * (s / 2 - lt / 2), top / 2)))
    yb = s / 2 - lt / 2
    if p["slats"] > 0.5:
        for k in range(3):
            x = (k - 1) * s * 0.28
            parts.append(_b((0.06, 0.04, hb * 0.8), (x, yb, hs + hb * 0.5)))
        parts.append(_b((s, 0.05, 0.1), (0, yb, hs + hb - 0.05)))
    else:
        parts.append(_b((s, 0.05, hb * 0.6), (0, yb, hs + hb * 0.65)))
    if p["arms"] > 0.5:
        for x in (1, -1):
            parts.append(_b((0.07, s, 0.06), (x * (s / 2 - 0.035), 0, hs + 0.3)))
            parts.append(_b((0.06, 0.06, 0.3), (x * (s / 2 - 0.035), -s / 2 + 0.05, hs + 0.15)))
    return parts


def _stool(p):
    h, r = p["height"], 0.5
    seat = Part(cylinder(r, 0.08, z0=h - 0.08, segments=int(p["sides"]))) if p["sides"] > 4 else _b((1.0, 1.0, 0.08), (0, 0, h - 0.04))
    legs = int(p["legs"])
    parts = [seat]
    for k in range(legs):
        a = 2 * math.pi * k / legs + math.pi / 4
        x, y = 0.36 * math.cos(a), 0.36 * math.sin(a)
        parts.append(_b((0.06, 0.06, h - 0.08), (x, y, (h - 0.08) / 2)))
    if p["ring"] > 0.5:
        ring = transform(tube_arc(0.36, 0.02, 0, 2 * math.pi, 24, 6), rotation("x", math.pi / 2), (0, 0, h * 0.35))
        parts.append(Part(ring, "none"))
    return parts


def _bench(p):
    ln, d, h = 1.0, p["depth"], p["height"]
    parts = [_b((ln, d, 0.05), (0, 0, h - 0.025))]
    for x in (1, -1):
        parts.append(_b((0.05, d * 0.9, h - 0.05), (x * (ln / 2 - 0.06), 0, (h - 0.05) / 2)))
    return parts


def _table(p):
    h, top = p["height"], 0.04
    if p["round"] > 0.5:
        parts = [Part(cylinder(0.5, top, z0=h - top, segments=32)), Part(cylinder(0.04, h - top, segments=12)), Part(cylinder(0.25, 0.03, segments=24))]
    else:
        parts = [_b((1.0, p["depth"], top), (0, 0, h - top / 2))]
        for x, y in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            parts.append(_b((0.05, 0.05, h - top), (x * 0.45, y * (p["depth"] / 2 - 0.05), (h - top) / 2)))
    return parts


def _shelf(p):
    w, d, h, n = 1.0, p["depth"], p["height"], int(p["levels"])
    t = 0.03
    parts = [_b((t, d, h), (w / 2 - t / 2, 0, h / 2)), _b((t, d, h), (-w / 2 + t / 2, 0, h / 2)), _b((w, 0.01, h), (0, d / 2 - 0.005, h / 2), collision="hull")]
    for k in range(n):
        z = t / 2 + k * (h - t) / max(n - 1, 1)
        parts.append(_b((w - 2 * t, d, t), (0, 0, z)))
    return parts


def _toy_car(p):
    ln, w, h = 1.0, p["width"], p["height"]
    r = 0.14
    parts = [_b((ln, w, h * 0.45), (0, 0, r + h * 0.2)), _b((ln * p["cabin"], w * 0.9, h * 0.35), (-0.05, 0, r + h * 0.6))]
    for x in (0.3, -0.3):
        for y in (1, -1):
            wheel = transform(cylinder(r, 0.08, z0=-0.04, segments=14), rotation("x", math.pi / 2), (x, y * (w / 2 - 0.02), r))
            parts.append(Part(wheel))
    return parts


def _blocks(p):
    n, s = int(p["count"]), 1.0
    parts = []
    for k in range(n):
        jitter = (0.08 * math.sin(3.1 * k + p["twist"]), 0.08 * math.cos(2.3 * k + p["twist"]))
        parts.append(_b((s, s, s), (jitter[0], jitter[1], s / 2 + k * s), rotation("z", 0.3 * k * p["twist"])))
    return parts


def _dice(p):
    return [_b((1, 1, 1), (0, 0, 0.5), rotation("z", p["turn"]))]


def _robot(p):
    parts = [_b((0.6, 0.4, 0.7), (0, 0, 0.65)), _b((0.4, 0.35, 0.35), (0, 0, 1.2))]
    for x in (0.15, -0.15):
        parts.append(_b((0.18, 0.22, 0.3), (x, 0, 0.15)))
    for x in (0.38, -0.38):
        parts.append(_b((0.14, 0.16, 0.55), (x, 0, 0.7)))
    parts.append(Part(cylinder(0.02, 0.15, z0=1.37, segments=6), "none"))
    return parts


def _hammer(p):
    ln = 1.0
    head = _b((p["head"] * 0.3, p["head"], 0.11), (ln / 2 - 0.1, 0, 0.065), rotation("z", math.pi / 2))
    return [_rod_x(0.045, ln * 0.95, -ln / 2, 0.065), head]


def _screwdriver(p):
    ln = 1.0
    hl = p["handle"]
    handle = Part(transform(cylinder(0.07, hl, segments=6), rotation("y", math.pi / 2), (-ln / 2, 0, 0.07)))
    return [handle, _rod_x(0.02, ln - hl, -ln / 2 + hl, 0.07, 8)]


def _wrench(p):
    ln = 1.0
    bar = _b((ln * 0.8, p["width"], 0.04), (0, 0, 0.02))
    ring = transform(tube_arc(p["width"] * 0.9, 0.04, 0, 2 * math.pi, 20, 8), rotation("x", math.pi / 2), (ln * 0.4, 0, 0.02))
    jaw = slab([(-0.1, -0.12), (0.05, -0.13), (0.1, -0.04), (0.0, -0.02), (0.0, 0.02), (0.1, 0.04), (0.05, 0.13), (-0.1, 0.12)], 0.04)
    return [bar, Part(ring), Part(transform(jaw, None, (-ln * 0.45, 0, 0)))]


def _flat_tool(p):
    """Spatulas, spoons, forks, knives: a handle along -x and a head along +x."""
    ln, hw, kind = 1.0, p["head_w"], int(p["kind"])
    handle = _b((ln * 0.6, 0.06, 0.03), (-ln * 0.2, 0, 0.04))
    x0 = ln * 0.1
    if kind == 0:  # spatula blade
        head = _b((ln * 0.4, hw, 0.012), (x0 + ln * 0.2, 0, 0.01))
        return [handle, head]
    if kind == 1:  # spoon bowl
        return [handle, Part(ellipsoid(ln * 0.15, hw / 2, 0.03, (x0 + ln * 0.14, 0, 0.03), 16, 6))]
    if kind == 2:  # fork tines
        parts = [handle, _b((ln * 0.12, hw, 0.015), (x0 + 0.06, 0, 0.03))]
        for k in range(4):
            parts.append(_b((ln * 0.2, 0.018, 0.012), (x0 + 0.12 + ln * 0.1, (k - 1.5) * hw / 4, 0.03)))
        return parts
    blade = slab([(0.0, -hw / 2), (ln * 0.36, -hw / 4), (ln * 0.4, hw / 2), (0.0, hw / 2)], 0.012, z0=0.02)
    return [handle, Part(transform(blade, None, (x0, 0, 0)))]


def _brush(p):
    return [_rod_x(0.035, 0.65, -0.5, 0.045, 10), _b((0.08, 0.1, 0.07), (0.18, 0, 0.045)), _b((0.22, p["width"], 0.05), (0.33, 0, 0.045))]


def _laptop(p):
    w, d = 1.0, p["depth"]
    t = 0.03
    a = p["open"]
    screen = box((w, d, t * 0.6), (0, d / 2, t * 0.3))
    screen = transform(screen, rotation("x", a), (0, d / 2, t))
    return [_b((w, d, t), (0, 0, t / 2)), Part(screen)]


def _slab_device(p):
    """Phones, remotes, tablets, soap, sponges: a rounded slab, optionally with buttons."""
    w, d, h = 1.0, p["width"], p["thick"]
    body = slab(_rounded_rect(w, d, min(d, w) * p["round"]), h)
    parts = [Part(body)]
    for k in range(int(p["buttons"])):
        button = transform(cylinder(d * 0.08, h * 0.3, z0=h, segments=8), None, (0.3 - 0.12 * k, 0, 0))
        parts.append(Part(button, "none"))
    return parts


def _mouse(p):
    return [Part(ellipsoid(0.5, p["width"] / 2, p["height"], (0, 0, 0), 20, 10)), _b((0.9, p["width"] * 0.9, 0.01), (0, 0, 0.005))]


def _headphones(p):
    r = 0.5
    band = transform(tube_arc(r, 0.04, 0.15, math.pi - 0.15, 20, 8), None, (0, 0, 0))
    cups = [Part(transform(cylinder(0.18, 0.12, segments=16), rotation("y", math.pi / 2), (s * (r - 0.06) - (0.12 if s > 0 else 0), 0, 0.1 + p["drop"]))) for s in (1, -1)]
    return [Part(transform(band, None, (0, 0, 0.2 + p["drop"])), "hull"), *cups]


def _speaker(p):
    h, d = p["height"], p["depth"]
    parts = [_b((1.0, d, h), (0, 0, h / 2))]
    for z, r in ((h * 0.68, 0.32), (h * 0.25, 0.16)):
        cone = transform(cylinder(r, 0.02, segments=20), rotation("x", math.pi / 2), (0, -d / 2, z))
        parts.append(Part(cone, "none"))
    return parts


def _frame(p):
    w, h, t, b = 1.0, p["height"], 0.05, p["border"]
    tilt = rotation("x", -0.2)
    parts = [_b((w, t, b), (0, 0, b / 2)), _b((w, t, b), (0, 0, h - b / 2)), _b((b, t, h), (w / 2 - b / 2, 0, h / 2)),
             _b((b, t, h), (-w / 2 + b / 2, 0, h / 2)), _b((w - 2 * b, t * 0.5, h - 2 * b), (0, 0.01, h / 2))]
    return [Part(transform(q.mesh, tilt, (0, 0, 0.02)), q.collision) for q in parts] + [_b((0.08, h * 0.5, 0.03), (0, h * 0.15, 0.015))]


def _clock(p):
    r = 0.5
    face = transform(cylinder(r, p["depth"], segments=32), rotation("x", math.pi / 2), (0, p["depth"] / 2, r))
    parts = [Part(face), _b((0.6, p["depth"] * 1.4, 0.05), (0, 0, 0.025))]
    if p["bells"] > 0.5:
        for x in (0.3, -0.3):
            parts.append(Part(ellipsoid(0.15, 0.15, 0.1, (x, 0, 2 * r + 0.02), 12, 6)))
    return parts


def _pen(p):
    ln, r = 1.0, p["radius"]
    sides = int(p["sides"])
    body = Part(transform(cylinder(r, ln * 0.85, segments=sides), rotation("y", math.pi / 2), (-ln / 2, 0, r)))
    tip = Part(transform(cylinder(r, ln * 0.15, segments=sides, r_top=r * 0.15), rotation("y", math.pi / 2), (ln * 0.35, 0, r)))
    return [body, tip]


def _stapler(p):
    ln, w = 1.0, p["width"]
    return [_b((ln, w, 0.08), (0, 0, 0.04)), _b((ln * 0.95, w * 0.85, 0.14), (0.02, 0, 0.17), rotation("y", p["tilt"]))]


def _cushion(p):
    w, d, h = 1.0, p["depth"], p["height"]
    body = ellipsoid(w / 2, d / 2, h / 2, (0, 0, h / 2), 24, 12)
    v = body.vertices.copy()
    squ = np.clip(np.abs(v[:, :2]) / np.array([w / 2, d / 2]), 0, 1)  # push towards a pillow's corners
    v[:, :2] *= (1 + p["corner"] * squ[:, ::-1])
    return [Part(type(body)(v, body.faces, body.uv))]


def _folded(p):
    w, d, n = 1.0, p["depth"], int(p["layers"])
    t = p["layer_h"]
    return [_b((w - 0.01 * k, d - 0.01 * k, t), (0, 0, t / 2 + k * t)) for k in range(n)]


def _tissue_box(p):
    h = p["height"]
    return [_b((1.0, 0.5, h), (0, 0, h / 2)), Part(ellipsoid(0.15, 0.08, 0.1, (0, 0, h), 12, 6), "none")]


def _dumbbell(p):
    ln = 1.0
    parts = [_rod_x(0.08, ln, -ln / 2, p["plate"])]
    for x in (ln / 2 - 0.2, -ln / 2 + 0.05):
        parts.append(_rod_x(p["plate"], 0.15, x, p["plate"], int(p["sides"])))
    return parts


def _board(p):
    w, d, t = 1.0, p["depth"], p["thick"]
    parts = [Part(slab(_rounded_rect(w, d, d * p["round"]), t))]
    if p["handle"] > 0.5:
        parts.append(_b((0.2, d * 0.35, t), (w / 2 + 0.09, 0, t / 2)))
    return parts


def _toaster(p):
    w, d, h = 1.0, p["depth"], p["height"]
    parts = [Part(slab(_rounded_rect(w, d, d * 0.25), h))]
    for y in (-0.12 * d, 0.12 * d):
        parts.append(_b((w * 0.7, d * 0.1, 0.01), (0, y, h + 0.005), collision="none"))
    parts.append(_b((0.05, 0.06, 0.15), (w / 2 + 0.02, 0, h * 0.6)))
    return parts


def _lantern(p):
    w, h = 1.0, p["height"]
    parts = [_b((w, w, 0.08), (0, 0, 0.04)), _b((w, w, 0.08), (0, 0, h - 0.04))]
    for x, y in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        parts.append(_b((0.06, 0.06, h), (x * (w / 2 - 0.03), y * (w / 2 - 0.03), h / 2)))
    parts.append(Part(cylinder(0.3, h - 0.16, z0=0.08, segments=16)))
    parts.append(Part(transform(tube_arc(0.25, 0.02, 0.0, math.pi, 12, 6), None, (0, 0, h)), "none"))
    return parts


BUILT_SHAPES: dict[str, tuple] = {
    "book_hard": (_book, {"width": (0.65, 0.8), "thick": (0.08, 0.22), "hard": (1, 1)}),
    "book_soft": (_book, {"width": (0.62, 0.72), "thick": (0.05, 0.15), "hard": (0, 0)}),
    "box_plain": (_box, {"depth": (0.5, 0.9), "height": (0.4, 0.8), "lid": (0, 0)}),
    "box_lidded": (_box, {"depth": (0.45, 0.7), "height": (0.3, 0.55), "lid": (1, 1)}),
    "box_open": (_open_box, {"depth": (0.55, 0.85), "height": (0.25, 0.5), "wall": (0.03, 0.05), "handle": (0, 0)}),
    "tray_flat": (_open_box, {"depth": (0.55, 0.75), "height": (0.05, 0.1), "wall": (0.02, 0.03), "handle": (0, 0)}),
    "basket_handle": (_open_box, {"depth": (0.5, 0.7), "height": (0.35, 0.5), "wall": (0.03, 0.04), "handle": (1, 1)}),
    "chair_panel": (_chair, {"seat_h": (0.85, 1.0), "back_h": (0.8, 1.0), "slats": (0, 0), "arms": (0, 0)}),
    "chair_slat": (_chair, {"seat_h": (0.85, 1.0), "back_h": (0.8, 1.1), "slats": (1, 1), "arms": (0, 0)}),
    "chair_arm": (_chair, {"seat_h": (0.8, 0.95), "back_h": (0.7, 0.9), "slats": (0, 0), "arms": (1, 1)}),
    "stool_round": (_stool, {"height": (0.9, 1.3), "sides": (24, 24), "legs": (3, 4), "ring": (0, 1)}),
    "stool_square": (_stool, {"height": (0.8, 1.1), "sides": (4, 4), "legs": (4, 4), "ring": (0, 0)}),
    "bench": (_bench, {"depth": (0.25, 0.35), "height": (0.3, 0.4)}),
    "table_round": (_table, {"height": (0.9, 1.2), "round": (1, 1), "depth": (1, 1)}),
    "table_square": (_table, {"height": (0.7, 1.0), "round": (0, 0), "depth": (0.6, 1.0)}),
    "shelf_unit": (_shelf, {"depth": (0.3, 0.45), "height": (0.8, 1.6), "levels": (2, 4)}),
    "toy_car": (_toy_car, {"width": (0.4, 0.5), "height": (0.4, 0.55), "cabin": (0.45, 0.6)}),
    "block_stack": (_blocks, {"count": (2, 3), "twist": (0.0, 1.0)}),
    "dice": (_dice, {"turn": (0.0, 0.8)}),
    "toy_robot": (_robot, {}),
    "hammer": (_hammer, {"head": (0.3, 0.4)}),
    "screwdriver": (_screwdriver, {"handle": (0.4, 0.5)}),
    "wrench": (_wrench, {"width": (0.08, 0.11)}),
    "spatula": (_flat_tool, {"head_w": (0.18, 0.26), "kind": (0, 0)}),
    "spoon": (_flat_tool, {"head_w": (0.14, 0.2), "kind": (1, 1)}),
    "fork": (_flat_tool, {"head_w": (0.12, 0.16), "kind": (2, 2)}),
    "knife": (_flat_tool, {"head_w": (0.08, 0.14), "kind": (3, 3)}),
    "paintbrush": (_brush, {"width": (0.12, 0.25)}),
    "laptop": (_laptop, {"depth": (0.65, 0.75), "open": (1.6, 2.0)}),
    "phone": (_slab_device, {"width": (0.45, 0.52), "thick": (0.04, 0.06), "round": (0.15, 0.25), "buttons": (0, 0)}),
    "remote": (_slab_device, {"width": (0.2, 0.28), "thick": (0.08, 0.12), "round": (0.3, 0.45), "buttons": (2, 3)}),
    "soap_bar": (_slab_device, {"width": (0.55, 0.7), "thick": (0.28, 0.38), "round": (0.4, 0.5), "buttons": (0, 0)}),
    "sponge": (_slab_device, {"width": (0.6, 0.7), "thick": (0.3, 0.45), "round": (0.05, 0.1), "buttons": (0, 0)}),
    "computer_mouse": (_mouse, {"width": (0.55, 0.65), "height": (0.3, 0.38)}),
    "headphones": (_headphones, {"drop": (0.0, 0.05)}),
    "speaker": (_speaker, {"height": (1.2, 1.6), "depth": (0.7, 0.9)}),
    "picture_frame": (_frame, {"height": (0.75, 1.3), "border": (0.06, 0.12)}),
    "clock": (_clock, {"depth": (0.15, 0.3), "bells": (0, 0)}),
    "alarm_clock": (_clock, {"depth": (0.35, 0.5), "bells": (1, 1)}),
    "pencil": (_pen, {"radius": (0.035, 0.045), "sides": (6, 6)}),
    "marker": (_pen, {"radius": (0.06, 0.08), "sides": (16, 16)}),
    "stapler": (_stapler, {"width": (0.22, 0.28), "tilt": (0.0, 0.06)}),
    "pillow": (_cushion, {"depth": (0.6, 0.75), "height": (0.18, 0.28), "corner": (0.1, 0.25)}),
    "towel": (_folded, {"depth": (0.6, 0.8), "layers": (2, 4), "layer_h": (0.04, 0.06)}),
    "tissue_box": (_tissue_box, {"height": (0.4, 0.6)}),
    "dumbbell": (_dumbbell, {"plate": (0.14, 0.2), "sides": (6, 16)}),
    "cutting_board": (_board, {"depth": (0.55, 0.7), "thick": (0.03, 0.05), "round": (0.05, 0.2), "handle": (0, 1)}),
    "toaster": (_toaster, {"depth": (0.55, 0.7), "height": (0.65, 0.85)}),
    "lantern": (_lantern, {"height": (1.3, 1.7)}),
}
"""Built shape variants: name -> (builder, parameter ranges)."""
