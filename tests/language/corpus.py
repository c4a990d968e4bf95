"""Reader of ``corpus.txt`` and the checker shared by the corpus tests and the benchmark."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

CORPUS_PATH = Path(__file__).with_name("corpus.txt")
#: Instructions for the motions of issue 16 (march, kick, clap...): their expected parameters
#: list only what the language layer decides; parameters named by the new actions' own
#: vocabulary entries are not compared (see :func:`check`, ``strict=False``).
NEW_ACTIONS_PATH = Path(__file__).with_name("corpus_new_actions.txt")
VALUE_ATOL = 1e-9  # parameters are SI floats computed from decimal text: exact up to rounding


@dataclass(frozen=True)
class Case:
    """One corpus line."""

    line: int
    text: str
    expected: tuple[dict, ...] | None  # None for a rejection
    error: str | None = None
    quoted: tuple[str, ...] = ()

    @property
    def id(self) -> str:
        return f"L{self.line}"


def _value(token: str):
    if token.endswith("deg"):
        return math.radians(float(token[:-3]))
    try:
        return float(token)
    except ValueError:
        return token


def load_corpus(path: Path = CORPUS_PATH) -> list[Case]:
    """All cases of a corpus file (default ``corpus.txt``), in order."""
    cases = []
    for n, raw in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        text, sep, expected = raw.rpartition(" | ")
        if not sep:
            raise ValueError(f"{path.name} line {n}: no ' | ' separator")
        expected = expected.strip()
        if expected.startswith("!"):
            error, *quoted = expected[1:].split(" ", 1)
            words = tuple(re.findall(r'"([^"]+)"', quoted[0])) if quoted else ()
            cases.append(Case(n, text, None, error, words))
            continue
        actions = []
        for part in expected.split(" ; "):
            name, _, rest = part.strip().partition(" ")
            overlay = name.startswith("+")
            # key=value, or key="a value with spaces" (an object reference)
            params = {k: (q if q else _value(v)) for k, v, q in re.findall(r'(\w+)=("([^"]*)"|\S+)', rest)}
            entry = {"action": name.lstrip("+"), "params": params}
            if overlay:
                entry["overlay"] = True
            actions.append(entry)
        cases.append(Case(n, text, tuple(actions)))
    return cases


def check(case: Case, *, strict: bool = True) -> str | None:
    """None if the parser does what the corpus says, else a one-line reason.

    ``strict=False``: the parameters listed must match, others stated by the parser are allowed
    (the corpus of new actions does not know every parameter name of their vocabulary).
    """
    from language import LanguageError, parse

    try:
        got = parse(case.text).to_dict()
    except LanguageError as e:
        if case.expected is not None:
            return f"{case.text!r}: unexpected {type(e).__name__}: {e}"
        if type(e).__name__ != case.error:
            return f"{case.text!r}: expected {case.error}, got {type(e).__name__}: {e}"
        missing = [w for w in case.quoted if f'"{w}"' not in str(e)]
        if missing or "\n" in str(e):
            return f"{case.text!r}: message does not quote {missing} on one line: {e}"
        return None
    if case.expected is None:
        return f"{case.text!r}: expected {case.error}, got {got['actions']}"
    if got["backend"] != "rules" or len(got["actions"]) != len(case.expected):
        return f"{case.text!r}: expected {list(case.expected)}, got {got['actions']}"
    for want, have in zip(case.expected, got["actions"], strict=True):
        if (want["action"] != have["action"] or want.get("overlay", False) != have.get("overlay", False)
                or (set(want["params"]) != set(have["params"]) if strict else not set(want["params"]) <= set(have["params"]))):
            return f"{case.text!r}: expected {list(case.expected)}, got {got['actions']}"
        for k, v in want["params"].items():
            h = have["params"][k]
            ok = math.isclose(h, v, rel_tol=0, abs_tol=VALUE_ATOL) if isinstance(v, float) else h == v
            if not ok:
                return f"{case.text!r}: {want['action']} {k} expected {v}, got {h}"
    return None
