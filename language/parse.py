"""``parse(text)``: the one entry point of the language layer."""

from __future__ import annotations

from typing import Any

from language.exceptions import BackendError
from language.plan import ActionPlan

BACKENDS = ("rules", "llm")


def parse(text: str, *, backend: str = "rules", **llm_options: Any) -> ActionPlan:
    """Actions of an English or Chinese instruction.

    Args:
        text: The instruction (``"wave your right hand twice, then squat"``, ``"深蹲三次"``).
        backend: ``rules`` (default: offline, deterministic, well under 1 ms) or ``llm`` (an
            OpenAI-compatible chat-completions server, see :func:`language.llm.parse_llm`).
        **llm_options: Options of the LLM backend: ``url``, ``model``, ``api_key``,
            ``timeout`` [s], ``json_mode``. Refused with the rules backend.

    Returns:
        The plan: validated actions, in order, with the stated parameters recorded.

    Raises:
        LanguageError: The instruction is empty, has unknown words, is ambiguous, asks for a
            value out of range, or the LLM backend failed (subclasses name which).
    """
    if backend == "rules":
        if llm_options:
            raise BackendError(f"the rules parser takes no options, got {', '.join(sorted(llm_options))}")
        # on first use: the face (``language.ActionPlan``, ``LanguageError``) then loads without the
        # lexicon, as `wbmp solve` reading a repeated request's actions from the motion cache does
        from language.rules import rules_plan

        return rules_plan(text)
    if backend == "llm":
        from language.llm import OPTIONS, parse_llm

        unknown = sorted(set(llm_options) - set(OPTIONS))
        if unknown:
            raise BackendError(f"unknown LLM option(s) {', '.join(unknown)}; known: {', '.join(OPTIONS)}")
        return parse_llm(text, **llm_options)
    raise BackendError(f"unknown parser backend {backend!r}; use one of {', '.join(BACKENDS)}")
