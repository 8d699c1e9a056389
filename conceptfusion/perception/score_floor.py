"""Score floors: the smallest median cosine score of a region that counts as found for a text query.

Each perceived encoder ships calibrated floors per setting (:data:`FLOOR_SETTINGS`) in its
metadata (:func:`encoder_score_floor`); the oracles' floors are derived, not tuned
(:data:`ORACLE_MIN_SCORE`, :data:`ORACLE_OPEN_MIN_SCORE`). A featurizer applies one floor per
setting (:func:`score_floor_for`), which :func:`conceptfusion.make_mapper` sets as
``MapperConfig.min_score``.
"""

from __future__ import annotations

from conceptfusion.perception.oracle import GROUNDED_ORACLE_MIN_SCORE
from conceptfusion.perception.oracle_floor import load_oracle_floor

__all__ = ["ORACLE_MIN_SCORE", "ORACLE_OPEN_MIN_SCORE", "FLOOR_SETTINGS", "encoder_score_floor", "score_floor_for",
           "score_floor_key"]

ORACLE_MIN_SCORE = load_oracle_floor()
"""Score floor with oracle features, derived, not tuned: read once, at import, from
:data:`~conceptfusion.perception.oracle_floor.ORACLE_FLOOR_FILE`, which
``python -m tower_training.oracle_floor --write`` writes (the midpoint between the lowest score of
an object's own wordings against its label and the highest score of those wordings against the
other objects' labels, over the floor-calibration scenes). A missing or broken file raises
:class:`~conceptfusion.errors.MissingFileError` / :class:`~conceptfusion.errors.CalibrationFileError`
naming it."""

ORACLE_OPEN_MIN_SCORE = GROUNDED_ORACLE_MIN_SCORE
"""Score floor with ``oracle-open`` features, derived from the construction (see
:data:`~conceptfusion.perception.oracle.GROUNDED_ORACLE_MIN_SCORE`), not tuned."""

FLOOR_SETTINGS = ("tabletop", "household", "search")
"""Where text queries are asked: a tabletop (objects close by; the floor every encoder calibrates
first), a household apartment (objects one to a few metres from a robot base's camera, 160x120
frames) or an apartment as the object-search agents see it (the same views at 320x240 with the
small-object proposals of :data:`~conceptfusion.perception.spec.SEARCH_PROPOSER`)."""

_FALLBACK = {"search": "household", "household": "tabletop"}


def score_floor_key(setting: str) -> str:
    """Where an encoder's metadata keeps its floor for ``setting``
    (``info["metrics"][score_floor_key(setting)]``): ``score_floor`` for tabletops,
    ``score_floor_<setting>`` for the others."""
    return "score_floor" if setting == "tabletop" else f"score_floor_{setting}"


def encoder_score_floor(encoder, setting: str = "tabletop") -> float | None:
    """The calibrated floor an encoder ships for ``setting``: ``info["metrics"]["score_floor"]``
    for tabletops, ``score_floor_household`` for apartments and ``score_floor_search`` for the
    search agents' view of them (:mod:`tower_training.room_floor`); a setting without its own
    floor falls back to household, then tabletop; None without any."""
    metrics = getattr(encoder, "info", {}).get("metrics", {}) if hasattr(encoder, "info") else {}
    while setting != "tabletop":
        if metrics.get(score_floor_key(setting)) is not None:
            return metrics[score_floor_key(setting)]
        setting = _FALLBACK[setting]
    return metrics.get(score_floor_key("tabletop"))


def score_floor_for(featurizer, setting: str = "tabletop") -> float | None:
    """The text-query floor a featurizer applies in ``setting`` (one of :data:`FLOOR_SETTINGS`):
    its ``score_floors[setting]`` when it keeps floors per setting, else its one ``score_floor``.

    Raises:
        ValueError: an unknown setting.
    """
    if setting not in FLOOR_SETTINGS:
        raise ValueError(f"setting: expected one of {', '.join(FLOOR_SETTINGS)}, got {setting!r}")
    floors = getattr(featurizer, "score_floors", None)
    return floors[setting] if floors else featurizer.score_floor
