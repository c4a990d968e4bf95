"""``wbmp parse TEXT [--json] [--parser rules|llm]``: show the actions a sentence asks for.

With ``--json`` the output is exactly ``{"actions": [{"action": NAME, "params": {...}}],
"backend": "rules"}`` in SI units (only the parameters the sentence states; an overlaid action
carries ``"overlay": true``). The LLM backend reads its key from ``WBMP_LLM_API_KEY`` or
``OPENAI_API_KEY``; ``--llm-url``/``--llm-model`` default to ``WBMP_LLM_URL``/``WBMP_LLM_MODEL``.
"""

from __future__ import annotations

import argparse
import json
import os

from wbmp.errors import CliError, ExitCode

KEY_VARIABLES = ("WBMP_LLM_API_KEY", "OPENAI_API_KEY")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "parse", help="turn an English or Chinese sentence into actions (no planning)",
        description="Parse an instruction into registry actions and print them. The default parser "
                    "is rule-based, offline and deterministic; --parser llm asks an OpenAI-compatible "
                    "chat-completions server (key from WBMP_LLM_API_KEY or OPENAI_API_KEY).",
        epilog='examples: wbmp parse "wave your right hand twice, then squat"   '
               'wbmp parse "深蹲三次" --json   '
               'wbmp parse "wave" --parser llm --llm-url http://127.0.0.1:11434/v1 --llm-model qwen2.5:7b',
    )
    p.add_argument("text", nargs="+", help="the instruction (quote it, or give it as several words)")
    p.add_argument("--json", action="store_true", help="print the plan as JSON")
    p.add_argument("--parser", choices=("rules", "llm"), default="rules", help="parser backend (default: rules)")
    p.add_argument("--llm-url", default=os.environ.get("WBMP_LLM_URL"),
                   help="OpenAI-compatible API base URL, e.g. http://127.0.0.1:11434/v1 (env WBMP_LLM_URL)")
    p.add_argument("--llm-model", default=os.environ.get("WBMP_LLM_MODEL"), help="model name (env WBMP_LLM_MODEL)")
    p.add_argument("--llm-timeout", type=float, default=30.0, help="seconds to wait for the server (default: 30)")
    p.set_defaults(run=run)


def llm_options(args: argparse.Namespace) -> dict:
    """Backend options for ``language.parse`` from the command line and the environment."""
    if args.parser != "llm":
        return {}
    if not args.llm_url:
        raise CliError("--parser llm needs --llm-url URL (or WBMP_LLM_URL)", ExitCode.USAGE)
    if not args.llm_model:
        raise CliError("--parser llm needs --llm-model NAME (or WBMP_LLM_MODEL)", ExitCode.USAGE)
    key = next((os.environ[v] for v in KEY_VARIABLES if os.environ.get(v)), None)
    return {"url": args.llm_url, "model": args.llm_model, "api_key": key, "timeout": args.llm_timeout}


def run(args: argparse.Namespace) -> int:
    from language import parse

    text = " ".join(args.text)
    plan = parse(text, backend=args.parser, **llm_options(args))
    if args.json:
        print(json.dumps(plan.to_dict(), ensure_ascii=False))
    else:
        print(plan.describe())
    return ExitCode.OK
