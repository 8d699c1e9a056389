"""Words that environments and agents share about a task (a base module: no dependencies).

An object-search episode may begin with an exploration budget before its first goal is revealed
("explore, then fetch"); during it the observation's ``goal`` is :data:`EXPLORE_GOAL`, a phrase
no object is described by, so an agent knows to explore and remember rather than search.

A household environment may also hand out the apartment's labelled floor plan (``room_plan``):
the observation's ``room_boxes`` and ``room_types`` (:data:`ROOM_TYPES`, :func:`rooms_from_plan`).
"""

__all__ = ["EXPLORE_GOAL", "ROOM_TYPES", "MAX_ROOMS", "rooms_from_plan"]

EXPLORE_GOAL = "explore the apartment"
"""The ``goal`` text of an object search's exploration phase."""

ROOM_TYPES = ("kitchen", "living room", "study", "bedroom", "bathroom", "dining room", "hallway", "office")
"""Room names a labelled floor plan (``room_plan``) can carry, in code order: ``room_types`` holds
``k + 1`` for ``ROOM_TYPES[k]`` and 0 for an unused row."""

MAX_ROOMS = 8
"""Rows of a room plan observation."""


def rooms_from_plan(obs) -> list:
    """The ``(name, [x_min, y_min, x_max, y_max])`` rooms of a room plan observation, in order
    (empty when the observation has none).

    Shape: ``obs["room_boxes"]`` (MAX_ROOMS, 4), ``obs["room_types"]`` (MAX_ROOMS,) -> list of
    ``(str, list of 4 float)``.
    """
    if "room_types" not in obs:
        return []
    return [(ROOM_TYPES[int(t) - 1], [float(v) for v in b]) for t, b in zip(obs["room_types"], obs["room_boxes"]) if int(t) > 0]
