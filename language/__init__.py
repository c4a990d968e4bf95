"""Language layer: English and Chinese instructions to registry actions.

``parse("wave your right hand twice, then squat")`` returns an :class:`ActionPlan` of
:class:`tasks.actions.Action` objects. The default ``rules`` backend is deterministic and
offline, driven by ``vocabulary.json`` (a new primitive needs words, not parser code); the
``llm`` backend asks an OpenAI-compatible server and validates its reply against the same
registry schema. Every failure is a :class:`LanguageError` with a one-line message.
"""

from typing import TYPE_CHECKING

from language.exceptions import (
    AmbiguousInstruction,
    BackendError,
    EmptyInstruction,
    InvalidParameter,
    LanguageError,
    LLMError,
    LLMReplyInvalid,
    LLMUnavailable,
    NoAction,
    SchemaViolation,
    UnknownWords,
    UnsupportedInstruction,
    UnsupportedSchema,
    VocabularyError,
)
from language.parse import BACKENDS, parse
from language.plan import ActionPlan, WordUse
from robots import lazy_face

if TYPE_CHECKING:
    from language.llm import check_api_key, check_timeout, check_url

# The LLM backend's option checks load its HTTP and TLS modules: on first use only.
_EXPORTS = {"check_api_key": "language.llm", "check_timeout": "language.llm", "check_url": "language.llm"}

__all__ = [
    "BACKENDS",
    "ActionPlan",
    "AmbiguousInstruction",
    "BackendError",
    "EmptyInstruction",
    "InvalidParameter",
    "LLMError",
    "LLMReplyInvalid",
    "LLMUnavailable",
    "LanguageError",
    "NoAction",
    "SchemaViolation",
    "UnknownWords",
    "UnsupportedInstruction",
    "UnsupportedSchema",
    "VocabularyError",
    "WordUse",
    "check_api_key",
    "check_timeout",
    "check_url",
    "parse",
]

__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
