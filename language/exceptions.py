"""Exceptions raised by the language layer.

Every error is a :class:`LanguageError` with a one-line message that quotes the words that
were not understood and says how to fix the instruction. ``wbmp`` maps them to exit code 2.
"""

from __future__ import annotations

from collections.abc import Sequence

from robots import WbmpError


class LanguageError(ValueError, WbmpError):
    """Base class of every error about an instruction (the CLI exits with code 2).

    The message is always one line: runs of whitespace (newlines in a quoted instruction
    included) become one space.
    """

    def __init__(self, message: str = "") -> None:
        super().__init__(" ".join(str(message).split()))


class EmptyInstruction(LanguageError):
    """The instruction holds no words (only blanks, punctuation or polite filler)."""


class UnknownWords(LanguageError):
    """Words that are in no vocabulary list.

    Attributes:
        words: The words not understood, in the order they appear.
        suggestions: Known action names close to them (may be empty).
    """

    def __init__(self, words: Sequence[str], known_actions: Sequence[str], suggestions: Sequence[str] = ()) -> None:
        self.words = tuple(words)
        self.suggestions = tuple(suggestions)
        quoted = ", ".join(f'"{w}"' for w in self.words)
        hint = ""
        if self.suggestions:
            hint = "; did you mean " + " or ".join(f'"{s}"' for s in self.suggestions) + "?"
        super().__init__(f"could not understand {quoted}: known actions are {', '.join(known_actions)}{hint}")


class NoAction(LanguageError):
    """A part of the instruction names no action (``"slowly, then squat"``)."""


class AmbiguousInstruction(LanguageError):
    """Two readings are possible (two actions with no ``then``, ``left`` and ``right`` at once...)."""


class UnsupportedInstruction(LanguageError):
    """Understood, but not something the actions can express (negation, two whole-body actions at once...)."""


class InvalidParameter(LanguageError):
    """A word or number does not fit the action (``"jump deep"``, ``"squat 5 m"``, ``"walk 90 degrees"``)."""


class BackendError(LanguageError):
    """The parser backend is unknown or could not be used."""


class LLMError(BackendError):
    """The LLM backend failed: unreachable server, timeout, HTTP error, or an invalid reply after the retry."""


class LLMUnavailable(LLMError):
    """No usable reply from the server (connection refused, timeout, HTTP error status)."""


class LLMReplyInvalid(LLMError):
    """The model's reply was not a valid action plan, even after one retry with the validation error."""


class VocabularyError(WbmpError):
    """The packaged vocabulary is inconsistent with itself or with the action registry (a bug)."""


class SchemaViolation(LanguageError):
    """An instance does not match the schema (the message lists where and why)."""

    def __init__(self, errors: list[str]) -> None:
        self.errors = errors
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        super().__init__(f"{errors[0]}{more}")


class UnsupportedSchema(ValueError):
    """The schema uses a keyword this validator does not implement (a bug, not bad input)."""
