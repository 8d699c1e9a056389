"""Looking names up in tables of named things, with "did you mean" for the nearest ones.

Agents, encoders, proposers, suites, assets, backends and planners are all plain dicts (or
sequences) keyed by name; an unknown name raises :class:`~conceptfusion.errors.UnknownNameError`
(a ``ValueError``) that names the nearest valid ones (:func:`difflib.get_close_matches`).
"""

from __future__ import annotations

import difflib
from typing import Callable, Iterable, Mapping, TypeVar

from conceptfusion.errors import UnknownNameError

__all__ = ["nearest_names", "did_you_mean", "unknown_name_error", "lookup", "lazy_exports"]

V = TypeVar("V")


def nearest_names(
    name: object, choices: Iterable[str], *, n: int = 3, cutoff: float = 0.4, key: Callable[[str], str] | None = None,
) -> list[str]:
    """Up to ``n`` of ``choices`` closest to ``name`` (most similar first; may be empty).

    ``key`` normalises both sides before comparing (``str.lower``: case-insensitive); the
    choices come back as given (the first of several with the same key).
    """
    choices = [str(c) for c in choices]
    if key is None:
        return difflib.get_close_matches(str(name), choices, n=n, cutoff=cutoff)
    by_key: dict[str, str] = {}
    for c in choices:
        by_key.setdefault(key(c), c)
    return [by_key[k] for k in difflib.get_close_matches(key(str(name)), list(by_key), n=n, cutoff=cutoff)]


def did_you_mean(
    name: object, choices: Iterable[str], *, n: int = 3, cutoff: float = 0.4, key: Callable[[str], str] | None = None,
) -> str:
    """``"; did you mean 'a', 'b'?"`` for the nearest choices, or ``""`` when none is close
    (arguments as :func:`nearest_names`)."""
    near = nearest_names(name, choices, n=n, cutoff=cutoff, key=key)
    return f"; did you mean {', '.join(repr(c) for c in near)}?" if near else ""


def unknown_name_error(
    kind: str, name: object, choices: Iterable[str], *, n: int = 3, cutoff: float = 0.4,
    key: Callable[[str], str] | None = None, listing: str | None = None, error: type[Exception] = UnknownNameError,
) -> Exception:
    """The error for an unknown ``name`` of a ``kind`` ("agent", "suite", ...), not raised.

    The message reads ``unknown KIND 'NAME'; did you mean ...? (KINDs: a, b, c)``; ``listing``
    replaces the text in brackets (``""`` drops it). ``n``, ``cutoff`` and ``key`` go to
    :func:`nearest_names`; ``error`` is the class of the error returned.
    """
    choices = [str(c) for c in choices]
    hint = did_you_mean(name, choices, n=n, cutoff=cutoff, key=key)
    tail = f"{kind}s: {', '.join(choices)}" if listing is None else listing
    return error(f"unknown {kind} {name!r}{hint}" + (f" ({tail})" if tail else ""))


def lookup(table: Mapping[str, V], name: object, kind: str, **kwargs) -> V:
    """``table[name]``, or :func:`unknown_name_error` raised (keyword arguments go to it)."""
    try:
        return table[name]  # type: ignore[index]
    except (KeyError, TypeError):
        raise unknown_name_error(kind, name, table, **kwargs) from None


def lazy_exports(package: str, sources: Mapping[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of a package whose public names (the keys of
    ``sources``) are imported from their module (the values) on first use and kept in the
    package, so that importing the package imports none of them. Any other name raises
    ``AttributeError`` listing the public ones."""
    import importlib
    import sys

    def __getattr__(name: str):
        if name not in sources:
            raise AttributeError(f"module {package!r} has no attribute {name!r} (public names: {', '.join(sorted(sources))})")
        value = getattr(importlib.import_module(sources[name]), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(sources))

    return __getattr__, __dir__
