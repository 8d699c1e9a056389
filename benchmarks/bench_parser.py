"""Exact-call accuracy of a spatial-question parser backend on a question file.

    python benchmarks/bench_parser.py tests/agents/data/spatial_questions_fresh1.jsonl
    python benchmarks/bench_parser.py FILE [--parser pattern] [--option base_url=http://...] [--json out.json]

The file is JSON lines in the format of ``tests/agents/data/spatial_questions.jsonl``: one
``{"question": str, "expected": "fn(a, b)" | null}`` per line (``null``: the parser must refuse).
The parser is built with :func:`agents.spatial.parser.make_parser` (``"pattern"`` is the same
``PatternParser()`` that ``tests/agents/test_spatial_parser.py`` scores); ``--option KEY=VALUE``
(repeatable; the value is read as JSON when it parses, else kept as a string) is passed on to
the backend, e.g. ``--parser llm --option base_url=http://127.0.0.1:8080/v1``; ``--parser semantic``
is the meaning-based parser (grammar fast path, MiniLM relation classes behind it).

A row counts as correct when the parser refuses a ``null`` row, or returns the expected function
with both arguments equal after :func:`agents.spatial.parser.clean_noun_phrase` on each side (case,
whitespace, leading articles/determiners, self-references), in order; this is the exact
signature comparison of the test. Reported:

* overall exact accuracy; exact accuracy on the spatial rows; refusal accuracy on the ``null``
  rows; how many spatial rows were refused; parse time per question (mean, median, max);
* per expected function: exact accuracy and right-function accuracy (arguments ignored);
* a confusion table, expected function (or ``refuse``) by returned function (or ``refuse``);
* every miss, with its kind (wrong function, wrong arguments, swapped arguments, refused a
  spatial question, answered a non-spatial one) and the parser's reason when it refused.
"""

from __future__ import annotations

import argparse
import collections
import json
import time
from pathlib import Path

from agents.spatial.parser import PARSERS, clean_noun_phrase, make_parser, parse_signature
from conceptfusion.spatial.comparators import COMPARATOR_NAMES

REFUSE = "refuse"
"""Row/column label for "no call" in the confusion table."""


def load_questions(path: Path) -> list[tuple[str, tuple[str, str, str] | None]]:
    """Rows of ``path`` as ``(question, (function, arg1, arg2) or None)``.

    Raises ``ValueError`` naming the line for a malformed row or an expected call that is not
    a valid signature.
    """
    rows = []
    with path.open(encoding="utf-8") as f:
        for lineno, line in enumerate(f, 1):
            if not line.strip():
                continue
            row = json.loads(line)
            if not isinstance(row, dict) or not isinstance(row.get("question"), str) or "expected" not in row:
                raise ValueError(f"{path}:{lineno}: expected an object with 'question' (str) and 'expected'")
            expected = row["expected"]
            if expected is None:
                rows.append((row["question"], None))
                continue
            res = parse_signature(expected)
            if not res.ok:
                raise ValueError(f"{path}:{lineno}: expected {expected!r} is not a valid call: {res.reason}")
            rows.append((row["question"], (res.function, *res.arguments)))
    return rows


def _norm(arguments) -> tuple[str, str]:
    return tuple(clean_noun_phrase(a) for a in arguments)


def score(parser, rows) -> dict:
    """Run ``parser`` on every row and tally the results (see the module docstring)."""
    per_fn = collections.defaultdict(lambda: {"n": 0, "exact": 0, "function": 0})
    confusion = collections.defaultdict(collections.Counter)
    misses = []
    times = []
    for question, expected in rows:
        t0 = time.perf_counter()
        res = parser.parse(question)
        times.append(time.perf_counter() - t0)
        got_fn = res.function if res.ok else REFUSE
        exp_fn = expected[0] if expected is not None else REFUSE
        confusion[exp_fn][got_fn] += 1
        stats = per_fn[exp_fn]
        stats["n"] += 1
        if expected is None:
            ok = not res.ok
            stats["function"] += ok
            kind = "answered a non-spatial question"
        else:
            want, got = _norm(expected[1:]), (_norm(res.arguments) if res.ok else None)
            same_fn = res.ok and res.function == expected[0]
            stats["function"] += same_fn
            ok = same_fn and got == want
            if not res.ok:
                kind = "refused a spatial question"
            elif not same_fn:
                kind = "wrong function"
            elif got == want[::-1]:
                kind = "swapped arguments"
            else:
                kind = "wrong arguments"
        stats["exact"] += ok
        if not ok:
            misses.append({
                "question": question,
                "expected": None if expected is None else f"{expected[0]}({expected[1]}, {expected[2]})",
                "got": res.signature,
                "reason": res.reason,
                "kind": kind,
            })
    n = len(rows)
    spatial = [s for fn, s in per_fn.items() if fn != REFUSE]
    n_spatial = sum(s["n"] for s in spatial)
    refuse = per_fn.get(REFUSE, {"n": 0, "exact": 0})
    return {
        "n": n,
        "exact": sum(s["exact"] for s in per_fn.values()),
        "n_spatial": n_spatial,
        "exact_spatial": sum(s["exact"] for s in spatial),
        "n_refuse": refuse["n"],
        "exact_refuse": refuse["exact"],
        "spatial_refused": sum(c[REFUSE] for fn, c in confusion.items() if fn != REFUSE),
        "per_function": {fn: dict(per_fn[fn]) for fn in (*COMPARATOR_NAMES, REFUSE) if fn in per_fn},
        "confusion": {fn: dict(c) for fn, c in confusion.items()},
        "misses": misses,
        "ms_per_question": 1000.0 * sum(times) / max(n, 1),
        "ms_median": 1000.0 * (sorted(times)[n // 2] if n % 2 else sum(sorted(times)[n // 2 - 1:n // 2 + 1]) / 2) if n else 0.0,
        "ms_max": 1000.0 * max(times, default=0.0),
    }


_SHORT = {
    "howFar": "howFar", "isToTheLeft": "left", "isToTheRight": "right", "onTopOf": "onTopOf",
    "under": "under", "isBigger": "bigger", "canFitInside": "canFit", "isContained": "contain",
}


def _pct(k: int, n: int) -> str:
    return f"{k}/{n} ({100.0 * k / n:.1f}%)" if n else "0/0 (-)"


def report(result: dict) -> str:
    """The human-readable summary of :func:`score`'s result."""
    lines = [
        f"overall exact    {_pct(result['exact'], result['n'])}",
        f"spatial exact    {_pct(result['exact_spatial'], result['n_spatial'])}"
        f"   (refused: {result['spatial_refused']})",
        f"refusals         {_pct(result['exact_refuse'], result['n_refuse'])}",
        f"time             {result['ms_per_question']:.2f} ms/question mean, {result['ms_median']:.2f} median,"
        f" {result['ms_max']:.1f} max (first call includes loading the backend)",
        "",
        f"{'function':<14}{'exact':>18}{'right function':>20}",
    ]
    for fn, s in result["per_function"].items():
        lines.append(f"{fn:<14}{_pct(s['exact'], s['n']):>18}{_pct(s['function'], s['n']):>20}")
    labels = [fn for fn in (*COMPARATOR_NAMES, REFUSE)
              if fn in result["confusion"] or any(fn in c for c in result["confusion"].values())]
    short = {fn: _SHORT.get(fn, fn[:8]) for fn in labels}
    lines += ["", "confusion (rows: expected, columns: returned)",
              " " * 14 + "".join(f"{short[fn]:>9}" for fn in labels)]
    for fn in labels:
        row = result["confusion"].get(fn, {})
        if row:
            lines.append(f"{fn:<14}" + "".join(f"{row.get(col, 0) or '.':>9}" for col in labels))
    kinds = collections.Counter(m["kind"] for m in result["misses"])
    lines += ["", f"misses: {len(result['misses'])}  " + ", ".join(f"{k}: {v}" for k, v in kinds.most_common())]
    for m in result["misses"]:
        got = m["got"] if m["got"] is not None else f"refused ({m['reason']})"
        lines.append(f"  [{m['kind']}] {m['question']!r}\n      expected {m['expected']}, got {got}")
    return "\n".join(lines)


def _option(text: str) -> tuple[str, object]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("questions", type=Path, help="JSON-lines question file")
    ap.add_argument("--parser", default="pattern", help=f"backend: {', '.join(PARSERS)}")
    ap.add_argument("--option", type=_option, action="append", default=[], metavar="KEY=VALUE",
                    help="backend option (repeatable)")
    ap.add_argument("--json", type=Path, default=None, help="also write the full result here")
    args = ap.parse_args()
    rows = load_questions(args.questions)
    parser = make_parser(args.parser, **dict(args.option))
    result = score(parser, rows)
    print(f"{args.questions} with the {args.parser!r} parser: {len(rows)} questions")
    print(report(result))
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
