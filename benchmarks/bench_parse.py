"""Parse time per instruction of the rule parser (target: < 1 ms), and its accuracy on the
phrasing corpus of issue 32 (in-scope accuracy, silent misreadings, refusals).

Run from the repository root::

    .venv/bin/python benchmarks/bench_parse.py            # table
    .venv/bin/python benchmarks/bench_parse.py --json     # machine-readable

Every accepted corpus sentence is parsed ``--repeat`` times after one warm-up (the vocabulary
is loaded once, at the first parse; that load is timed separately). Reports the mean, median,
95th percentile and maximum of the per-instruction time, for English and Chinese separately,
and exits 1 if the median is above the target. Timings are wall-clock on a shared machine.

The phrasing corpus (``tests/language/corpus/sentences.jsonl``, labelled before the parser was
changed for it) is graded by ``tests/language/phrasings.py``: accuracy over the in-scope
sentences, the silent misreadings (exit 0, not what was said: target 0), and the refusals.
``--misread`` lists the misread sentences, ``--refused`` the refused in-scope ones.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = 1e-3  # [s] per instruction
CJK = re.compile(r"[\u3400-\u9fff]")


def sentences() -> list[str]:
    """The accepted sentences of ``corpus.txt`` and the in-scope ones of the phrasing corpus."""
    sys.path.insert(0, str(ROOT))
    from language import LanguageError, parse
    from tests.language.corpus import load_corpus
    from tests.language.phrasings import load

    out = [c.text for c in load_corpus() if c.expected is not None]
    for s in load():
        try:
            parse(s.text)
        except LanguageError:
            continue
        out.append(s.text)
    return out


def measure(texts: list[str], repeat: int) -> dict:
    """Per-instruction times [s] of the rule parser."""
    from language import parse
    from language.lexicon import get_lexicon

    get_lexicon.cache_clear()  # time a fresh load (sentences() parsed with it already)
    t0 = time.perf_counter()
    get_lexicon()
    load = time.perf_counter() - t0
    for t in texts:  # warm-up
        parse(t)
    times: dict[str, list[float]] = {"en": [], "zh": []}
    for _ in range(repeat):
        for t in texts:
            t0 = time.perf_counter()
            parse(t)
            times["zh" if CJK.search(t) else "en"].append(time.perf_counter() - t0)
    out = {"vocabulary_load_s": load, "instructions": len(texts), "repeat": repeat, "target_s": TARGET}
    for lang, ts in (*times.items(), ("all", times["en"] + times["zh"])):
        ts = sorted(ts)
        out[lang] = {
            "n": len(ts),
            "mean_s": statistics.fmean(ts),
            "median_s": statistics.median(ts),
            "p95_s": ts[int(0.95 * (len(ts) - 1))],
            "max_s": ts[-1],
        }
    return out


def accuracy() -> dict:
    """Scores on the phrasing corpus (see ``tests.language.phrasings.score``)."""
    sys.path.insert(0, str(ROOT))
    from tests.language.phrasings import load, score

    return score(load())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20, help="passes over the corpus (default: 20)")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--misread", action="store_true", help="list the silently misread sentences")
    ap.add_argument("--refused", action="store_true", help="list the refused in-scope sentences")
    args = ap.parse_args(argv)
    result = measure(sentences(), args.repeat)
    acc = accuracy()
    outcomes = acc.pop("outcomes")
    result["phrasings"] = acc
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"phrasing corpus: {acc['sentences']} sentences, {acc['in_scope']} in scope: "
              f"{acc['in_scope_right']} right ({acc['accuracy_in_scope']:.1%}), "
              f"{acc['refused_in_scope']} refused; silent misreadings {acc['misread']}; "
              f"refusals {acc['refused']} ({acc['refused'] / acc['sentences']:.1%} of all), "
              f"{acc['refusal_words_not_named']} without the labelled words")
        for s, outcome, did in outcomes:
            if (args.misread and outcome == "misread") or (args.refused and outcome == "refused"):
                print(f"  {outcome}: {s.text!r} -> {did}")
        print(f"rule parser, {result['instructions']} corpus instructions x {args.repeat}; "
              f"vocabulary load {result['vocabulary_load_s'] * 1e3:.1f} ms (once)")
        print(f"{'':4} {'n':>6} {'mean':>9} {'median':>9} {'p95':>9} {'max':>9}   [us per instruction]")
        for lang in ("en", "zh", "all"):
            r = result[lang]
            print(f"{lang:4} {r['n']:6d} {r['mean_s'] * 1e6:9.1f} {r['median_s'] * 1e6:9.1f} "
                  f"{r['p95_s'] * 1e6:9.1f} {r['max_s'] * 1e6:9.1f}")
        ok = "meets" if result["all"]["median_s"] < TARGET else "MISSES"
        print(f"median {result['all']['median_s'] * 1e6:.0f} us {ok} the {TARGET * 1e6:.0f} us target")
    return 0 if result["all"]["median_s"] < TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
