"""ActionPlan: what a parser backend returns.

An :class:`ActionPlan` holds the actions in order (each a validated
:class:`tasks.actions.Action`, with the registry defaults filled in) and remembers which
parameters the sentence actually stated. :meth:`ActionPlan.to_dict` gives only the stated
ones, so ``"squat"`` prints ``{"action": "squat", "params": {}}`` and the defaults stay the
registry's (or the robot's) business when the action is compiled.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from language.exceptions import LanguageError, UnsupportedInstruction
from tasks import MAX_ACTIONS, REGISTRY, Action, TaskDefinitionError

#: What a word of the instruction did (``WordUse.role``).
ROLES = (
    "action",            # names the action (detail: its name)
    "parameter",         # sets a parameter (detail: "arm=left", "duration=4 s")
    "object",            # a reference to a scene object (detail: "object=the red box")
    "count",             # a count (detail: "repeat=3", or "2 copies" for actions without a count)
    "unit",              # the unit of the number before it (detail: "cm")
    "body part",         # a body word that names or qualifies the action (detail: "hand")
    "in place",          # "in place", "原地": turns walk/step into march, or confirms a motion on the spot
    "stop",              # a final "stop", "停下": ends the sequence
    "no effect",         # understood, changes nothing for this action ("squat down", "raise high")
    "not used",          # accepted but not expressed: mood/style words, a speed for an action without one
    "subject",           # "a person", "he", "这个人"
    "verb form",         # "is", "starts to", "正在"
    "sequence",          # "then", "and", "然后"
    "at the same time",  # "while", "同时"
    "again",             # "again", "再来一次"
    "filler",            # "please", "the", "请"
)


@dataclass(frozen=True, slots=True)
class ParsedAction:
    """An action and the names of the parameters the sentence stated (the rule parser's output)."""

    action: Action
    given: frozenset[str]


@dataclass(frozen=True, slots=True)
class WordUse:
    """What one word or phrase of an instruction did.

    Attributes:
        text: The words as written (normalized: lower case, NFKC).
        role: One of :data:`ROLES`.
        detail: What exactly (``"arm=left"``, ``"mood or style: wbmp cannot show it"``).
        action: 1-based index in :attr:`ActionPlan.actions` of the action it belongs to, if any.
    """

    text: str
    role: str
    detail: str = ""
    action: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """``{"text", "role"}`` plus ``"detail"`` and ``"action"`` when set."""
        out: dict[str, Any] = {"text": self.text, "role": self.role}
        if self.detail:
            out["detail"] = self.detail
        if self.action is not None:
            out["action"] = self.action
        return out


@dataclass(frozen=True, slots=True, kw_only=True)
class ActionPlan:
    """Parsed actions of one instruction.

    Attributes:
        actions: Actions in order; an action with ``overlay=True`` runs at the same time as the
            one before it (an upper-body action on a lower-body one). At most
            :data:`tasks.limits.MAX_ACTIONS` (more: :class:`UnsupportedInstruction`, exit 2).
        backend: Parser that produced it (``rules`` or ``llm``).
        text: The instruction as given.
        given: For each action, the names of the parameters the instruction stated (the other
            entries of ``Action.params`` are registry defaults).
        words: What each word of the instruction did, in order (rule parser only; empty for
            the LLM backend and for a plan read back with :meth:`from_dict`). Not compared.
    """

    actions: tuple[Action, ...]
    backend: str
    text: str
    given: tuple[frozenset[str], ...] = ()
    words: tuple[WordUse, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "actions", tuple(self.actions))
        if len(self.actions) > MAX_ACTIONS:
            raise UnsupportedInstruction(
                f"the instruction asks for {len(self.actions)} actions; wbmp plans at most {MAX_ACTIONS} at a "
                "time: split the instruction into several shorter ones"
            )
        if not self.given:
            given = tuple(frozenset(k for k, v in a.params.items() if v is not None) for a in self.actions)
            object.__setattr__(self, "given", given)
        else:
            object.__setattr__(self, "given", tuple(frozenset(g) for g in self.given))
        if len(self.given) != len(self.actions):
            raise ValueError(f"ActionPlan: {len(self.given)} 'given' sets for {len(self.actions)} actions")

    def stated_params(self, index: int) -> dict[str, Any]:
        """Parameters of action ``index`` that the instruction stated (SI units)."""
        action = self.actions[index]
        order = [p.name for p in REGISTRY[action.name].params]  # registry order: stable output
        return {k: (list(v) if isinstance(v, tuple) else v)
                for k in order if k in self.given[index] and (v := action.params.get(k)) is not None}

    def to_dict(self) -> dict[str, Any]:
        """``{"actions": [{"action": NAME, "params": {...}}], "backend": NAME}`` with stated params only."""
        out = []
        for i, action in enumerate(self.actions):
            entry: dict[str, Any] = {"action": action.name, "params": self.stated_params(i)}
            if action.overlay:
                entry["overlay"] = True
            out.append(entry)
        return {"actions": out, "backend": self.backend}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, text: str = "") -> ActionPlan:
        """Inverse of :meth:`to_dict` (LanguageError on bad content)."""
        if not isinstance(data, Mapping) or not isinstance(data.get("actions"), Sequence) or isinstance(data.get("actions"), str):
            raise LanguageError("an action plan must be an object with an 'actions' list")
        if len(data["actions"]) > MAX_ACTIONS:
            raise UnsupportedInstruction(
                f"the instruction asks for {len(data['actions'])} actions; wbmp plans at most {MAX_ACTIONS} at a "
                "time: split the instruction into several shorter ones"
            )
        actions, given = [], []
        for i, entry in enumerate(data["actions"]):
            try:
                action = Action.from_dict(entry)
            except TaskDefinitionError as e:
                raise LanguageError(f"actions[{i}]: {e}") from None
            actions.append(action)
            given.append(frozenset((entry.get("params") or {}).keys()))
        if not actions:
            raise LanguageError("an action plan needs at least one action")
        return cls(actions=tuple(actions), backend=str(data.get("backend", "rules")), text=text, given=tuple(given))

    def to_record(self) -> dict[str, Any]:
        """Everything of the plan as JSON (every parameter, the stated names, the words): the
        motion cache keeps it beside a request, so that a repeat is answered without parsing the
        sentence again; :meth:`from_record` gives back an equal plan, words included."""
        return {"text": self.text, "backend": self.backend,
                "actions": [a.to_dict() for a in self.actions],
                "given": [sorted(g) for g in self.given],
                "words": self.words_dict()}

    @classmethod
    def from_record(cls, data: Mapping[str, Any]) -> ActionPlan:
        """Inverse of :meth:`to_record` (LanguageError on bad content)."""
        try:
            words = tuple(WordUse(text=str(w["text"]), role=str(w["role"]), detail=str(w.get("detail", "")),
                                  action=None if w.get("action") is None else int(w["action"]))
                          for w in data["words"])
            return cls(actions=tuple(Action.from_dict(a) for a in data["actions"]), backend=str(data["backend"]),
                       text=str(data["text"]), given=tuple(frozenset(str(n) for n in g) for g in data["given"]),
                       words=words)
        except (KeyError, TypeError, ValueError, AttributeError, RecursionError, TaskDefinitionError) as e:
            raise LanguageError(f"not an action plan record ({type(e).__name__}: {str(e)[:120]})") from None

    def words_dict(self) -> list[dict[str, Any]]:
        """:attr:`words` as JSON-ready dicts (``wbmp parse --json`` prints them under ``"words"``)."""
        return [w.to_dict() for w in self.words]

    def describe_words(self) -> str:
        """One line per word: the words, what they did, and the action they belong to."""
        if not self.words:
            return ""
        width = min(max(len(w.text) for w in self.words), 24)
        lines = []
        for w in self.words:
            where = f" [action {w.action}]" if w.action is not None else ""
            detail = f": {w.detail}" if w.detail else ""
            lines.append(f"  {w.text:<{width}}  {w.role}{detail}{where}")
        return "\n".join(lines)

    def __len__(self) -> int:
        return len(self.actions)

    def describe(self) -> str:
        """Human-readable lines, one per action: stated parameters, then the defaults used."""
        lines = []
        for i, action in enumerate(self.actions):
            schema = REGISTRY[action.name]
            stated = self.stated_params(i)
            defaults = {k: v for k, v in action.params.items() if k not in stated and v is not None}

            def fmt(d: Mapping[str, Any]) -> str:
                parts = []
                for k, v in d.items():
                    unit = schema.param(k).unit  # noqa: B023 - fmt runs within the iteration
                    if isinstance(v, float):
                        v = f"{v:.4g}"
                    parts.append(f"{k}={v}" + (f" {unit}" if unit and unit != "count" else ""))
                return ", ".join(parts)

            prefix = "   + at the same time: " if action.overlay else f"{sum(not a.overlay for a in self.actions[: i + 1])}. "
            line = f"{prefix}{action.name}"
            if stated:
                line += f"  {fmt(stated)}"
            if defaults:
                line += f"  (defaults: {fmt(defaults)})"
            lines.append(line)
        return "\n".join(lines)
