"""Words that environments and agents share about a task (a base module: no dependencies).

An object-search episode may begin with an exploration budget before its first goal is revealed
("explore, then fetch"); during it the observation's ``goal`` is :data:`EXPLORE_GOAL`, a phrase
no object is described by, so an agent knows to explore and remember rather than search.
"""

__all__ = ["EXPLORE_GOAL"]

EXPLORE_GOAL = "explore the apartment"
"""The ``goal`` text of an object search's exploration phase."""
