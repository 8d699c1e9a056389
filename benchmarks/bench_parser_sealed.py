"""Aggregate figures of spatial-question parsers on a sealed question set, and nothing else.

    python benchmarks/bench_parser_sealed.py tests/agents/data/spatial_questions_fresh3.jsonl
    python benchmarks/bench_parser_sealed.py FILE [--parser pattern --parser semantic] [--json out.json]

Unlike ``bench_parser.py`` this prints no question, no expected call and no miss: a sealed set
is measured once and must not be read, so only totals come out. The file is JSON lines, one
``{"question": str, "expected": "fn(a, b)" | null, "kind": str}`` per line (``kind`` optional).

Per parser:

* ``exact``: rows whose returned signature equals ``expected`` (a refusal equals ``null``);
* ``confidently_wrong``: rows answered with a call whose signature differs from ``expected``,
  answers to out-of-scope (``null``) rows included: the error a caller cannot see;
* ``refused``: rows with no call (right or wrong);
* per ``kind``: ``n``, ``exact`` and ``confidently_wrong``.

Rates are over all rows of the file.
"""

from __future__ import annotations

import argparse
import collections
import json
from pathlib import Path

from agents.spatial.parser import make_parser


def load_rows(path: Path) -> list[dict]:
    """The JSON-lines rows of ``path`` (blank lines skipped)."""
    with path.open(encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def aggregate(parser, rows: list[dict]) -> dict:
    """Totals of ``parser`` on ``rows`` (see the module doc); no per-row detail is kept."""
    totals = collections.Counter()
    kinds: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for row in rows:
        got = parser.parse(row["question"]).signature
        kind = kinds[row.get("kind", "all")]
        exact, wrong = got == row["expected"], got is not None and got != row["expected"]
        for tally in (totals, kind):
            tally["n"] += 1
            tally["exact"] += exact
            tally["confidently_wrong"] += wrong
            tally["refused"] += got is None
    n = totals["n"]
    return {
        "n": n,
        "exact": totals["exact"],
        "exact_rate": totals["exact"] / n,
        "confidently_wrong": totals["confidently_wrong"],
        "confidently_wrong_rate": totals["confidently_wrong"] / n,
        "refused": totals["refused"],
        "refusal_rate": totals["refused"] / n,
        "per_kind": {k: {"n": c["n"], "exact": c["exact"], "exact_rate": c["exact"] / c["n"],
                         "confidently_wrong": c["confidently_wrong"]} for k, c in sorted(kinds.items())},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("path", type=Path)
    ap.add_argument("--parser", action="append", help="backend name (repeatable; default pattern and semantic)")
    ap.add_argument("--json", type=Path, help="also write the figures here")
    args = ap.parse_args(argv)
    rows = load_rows(args.path)
    figures = {}
    for name in args.parser or ["pattern", "semantic"]:
        fig = figures[name] = aggregate(make_parser(name), rows)
        print(f"{name}: exact {fig['exact']}/{fig['n']} ({fig['exact_rate']:.1%}), "
              f"confidently wrong {fig['confidently_wrong']} ({fig['confidently_wrong_rate']:.1%}), "
              f"refused {fig['refused']} ({fig['refusal_rate']:.1%})")
        for kind, k in fig["per_kind"].items():
            print(f"  {kind:15s} exact {k['exact']}/{k['n']} ({k['exact_rate']:.1%}), confidently wrong {k['confidently_wrong']}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
