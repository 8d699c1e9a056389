"""The offline planner's general knowledge: ``agents/instruct/vocabulary.json``, from the object library.

The offline language planner (:mod:`agents.instruct.offline`) knows the object categories a home
holds and what each is for, as a language model would. Agents may not read the simulator's
asset library, so that knowledge ships as a data file written from it: per category its name,
synonyms, function phrases and "a <group>" for every taxonomy group above it.

    python -m harness.planner_vocabulary            # (re)writes agents/instruct/vocabulary.json
    python -m harness.planner_vocabulary --check    # exit 1 if the shipped file differs
"""

from __future__ import annotations

import argparse
import json
import sys

from agents.instruct.offline import VOCABULARY_FILE
from conceptfusion.io_utils import atomic_write_text

__all__ = ["vocabulary_text", "main"]


def vocabulary_text() -> str:
    """The vocabulary file's text, derived from :func:`sim_envs.assets.library.catalogue`."""
    from sim_envs.assets.library import catalogue

    cat = catalogue()
    categories = {}
    for name in sorted(cat.categories):
        c = cat.categories[name]
        groups = [f"a {g}" for g in cat.ancestors(name) if g not in ("object", name)]
        categories[name] = [name, *c.synonyms, *c.functions, *groups]
    return json.dumps({"format": "cf-planner-vocabulary", "version": 1, "categories": categories}, indent=1) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.planner_vocabulary", description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare with the shipped file instead of writing it")
    args = ap.parse_args(argv)
    text = vocabulary_text()
    if args.check:
        same = VOCABULARY_FILE.is_file() and VOCABULARY_FILE.read_text() == text
        print(f"{VOCABULARY_FILE}: {'matches' if same else 'differs from'} the object library")
        return 0 if same else 1
    atomic_write_text(VOCABULARY_FILE, text)
    print(f"wrote {VOCABULARY_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
