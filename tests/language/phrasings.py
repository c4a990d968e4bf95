"""Reader and grader of the phrasing corpus (``corpus/sentences.jsonl``, issue 32).

Shared by ``test_phrasings.py`` and ``benchmarks/bench_parse.py``. A sentence's outcome is one of

- ``right``: the plan is the labelled one (or, for a ``refuse`` label, the refusal quotes the
  labelled words);
- ``misread``: exit 0 with a plan that is not what was said: other actions, a parameter value
  that differs, a parameter stated that the label does not list, or any plan for a ``refuse``
  label (a *silent misreading*);
- ``refused``: a one-line ``LanguageError`` for an in-scope sentence (honest, not right);
- ``unnamed``: a refusal of a ``refuse`` sentence whose message does not quote the words.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from tests.language.corpus import VALUE_ATOL, _value

PATH = Path(__file__).parent / "corpus" / "sentences.jsonl"
ANY = "*"  # a parameter whose value is not compared and which may be absent


@dataclass(frozen=True)
class Sentence:
    """One labelled sentence."""

    line: int
    text: str
    lang: str
    style: str
    in_scope: bool
    expected: tuple[dict, ...] | None  # None: refuse
    refuse: tuple[str, ...] = ()

    @property
    def id(self) -> str:
        return f"S{self.line}"


def _actions(expect: str) -> tuple[dict, ...]:
    out = []
    for part in expect.split(" ; "):
        name, _, rest = part.strip().partition(" ")
        params = {k: (q if q else (ANY if v == ANY else _value(v)))
                  for k, v, q in re.findall(r'(\w+)=("([^"]*)"|\S+)', rest)}
        out.append({"action": name.lstrip("+"), "params": params, "overlay": name.startswith("+")})
    return tuple(out)


def load(path: Path = PATH) -> list[Sentence]:
    """Every sentence of the corpus, in file order."""
    out = []
    for n, raw in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        r = json.loads(raw)
        expect = r.get("expect")
        out.append(Sentence(n, r["text"], r["lang"], r["style"], bool(r["in_scope"]),
                            _actions(expect) if expect else None, tuple(r.get("refuse", ()))))
    return out


def _equal(h, v) -> bool:
    if isinstance(v, float) or isinstance(h, float):
        return isinstance(h, (int, float)) and isinstance(v, (int, float)) \
            and math.isclose(h, v, rel_tol=0, abs_tol=VALUE_ATOL)
    return h == v


def _same(want: dict, have: dict) -> bool:
    """The motion is the labelled one: every parameter has the value the label gives, or else
    the registry's default (a parameter stated at its default value is what was said)."""
    from tasks.actions import REGISTRY

    if want["action"] != have["action"] or want["overlay"] != bool(have.get("overlay", False)):
        return False
    defaults = {p.name: p.default for p in REGISTRY[have["action"]].params}
    got = {**defaults, **have["params"]}
    for k in set(have["params"]) - set(want["params"]):
        if not _equal(have["params"][k], defaults.get(k)):
            return False
    for k, v in want["params"].items():
        if v == ANY:
            continue
        if k not in got:
            return False
        h = got[k]
        if not _equal(h, v):
            return False
    return True


def grade(s: Sentence, parse=None) -> tuple[str, str]:
    """(outcome, what the parser did) for one sentence; see the module docstring."""
    from language import LanguageError
    from language import parse as default_parse

    try:
        got = (parse or default_parse)(s.text).to_dict()["actions"]
    except LanguageError as e:
        msg = str(e)
        if s.expected is not None:
            return "refused", msg
        quoted = re.findall(r'"([^"]*)"', msg)
        named = all(any(w in q for q in quoted) for w in s.refuse) and "\n" not in msg
        return ("right" if named else "unnamed"), msg
    shown = " ; ".join(("+" if a.get("overlay") else "") + a["action"] + "".join(
        f" {k}={v}" for k, v in a["params"].items()) for a in got)
    if s.expected is None or len(got) != len(s.expected):
        return "misread", shown
    ok = all(_same(w, h) for w, h in zip(s.expected, got, strict=True))
    return ("right" if ok else "misread"), shown


def score(sentences: list[Sentence], parse=None) -> dict:
    """Counts over the corpus: accuracy on in-scope sentences, misreadings, refusals."""
    outcomes = [(s, *grade(s, parse)) for s in sentences]
    inscope = [o for o in outcomes if o[0].in_scope]
    right_in = sum(o[1] == "right" for o in inscope)
    return {
        "sentences": len(sentences),
        "in_scope": len(inscope),
        "in_scope_right": right_in,
        "accuracy_in_scope": right_in / max(len(inscope), 1),
        "misread": sum(o[1] == "misread" for o in outcomes),
        "refused": sum(o[1] in ("refused", "unnamed") or (o[0].expected is None and o[1] == "right")
                       for o in outcomes),
        "refused_in_scope": sum(o[1] == "refused" for o in inscope),
        "refusal_words_not_named": sum(o[1] == "unnamed" for o in outcomes),
        "outcomes": outcomes,
    }
