"""``wbmp parse TEXT [--json] [--parser rules|llm]``: show the actions a sentence asks for.

With ``--json`` the output is ``{"actions": [{"action": NAME, "params": {...}}], "backend":
"rules", "words": [...]}`` in SI units (only the parameters the sentence states; an overlaid
action carries ``"overlay": true``). ``words`` (rule parser only) says what each word did:
``{"text": "slowly", "role": "parameter", "detail": "duration=4 s", "action": 1}``; roles are
``language.plan.ROLES`` (action, parameter, count, unit, not used, filler...). The text output
lists the same after the actions. The LLM backend reads its key from ``WBMP_LLM_API_KEY`` or
``OPENAI_API_KEY``; ``--llm-url``/``--llm-model`` default to ``WBMP_LLM_URL``/``WBMP_LLM_MODEL``.
``--llm-timeout`` bounds each whole request to the server (connect to last byte).
``--motions DIR`` (or ``WBMP_MOTIONS``): a sentence that names no known action but a clip of
that motion library shows the clip (``"clip"`` in the JSON, ``"actions"`` empty) and its words,
as ``wbmp solve --motions`` picks it; none: refused as without it.
``--scene FILE`` grounds every object word in that scene (which of its objects the words name),
refusing with exit 3 as ``wbmp solve`` would when none or several match.

:func:`llm_options` checks the URL, the timeout and the key before any work (``wbmp solve`` uses
it too), so a bad value is a one-line usage error (exit 2) that never repeats the key.
"""

from __future__ import annotations

import argparse
import json
import os

from wbmp.errors import CliError, ExitCode, require_instruction

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
    p.add_argument("--scene", metavar="FILE", default=None,
                   help="scene JSON file: show which of its objects each object word names (docs/scenes.md)")
    p.add_argument("--motions", metavar="DIR", default=os.environ.get("WBMP_MOTIONS"),
                   help="a motion library (BVH clips with a clips.csv of labels): a sentence that names no "
                        "known action but a clip's label shows that clip, as wbmp solve --motions would "
                        "retarget it (docs/retarget.md; env WBMP_MOTIONS)")
    p.add_argument("--llm-url", default=os.environ.get("WBMP_LLM_URL"),
                   help="OpenAI-compatible API base URL, e.g. http://127.0.0.1:11434/v1 (env WBMP_LLM_URL)")
    p.add_argument("--llm-model", default=os.environ.get("WBMP_LLM_MODEL"), help="model name (env WBMP_LLM_MODEL)")
    p.add_argument("--llm-timeout", type=timeout_seconds, default=30.0, metavar="SECONDS",
                   help="limit for each whole request to the server, connect to last byte "
                        "(default: 30, at most 3600)")
    p.set_defaults(run=run)


def timeout_seconds(text: str) -> float:
    """``--llm-timeout`` value: a finite number of seconds above 0, at most 3600."""
    from language import BackendError, check_timeout

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, e.g. 30, got {text[:40]!r}") from None
    try:
        return check_timeout(value, name="the timeout")
    except BackendError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def llm_options(args: argparse.Namespace) -> dict:
    """Backend options for ``language.parse`` from the command line and the environment.

    Raises:
        CliError: (exit 2) no URL or model, a URL that is not http(s)://host[:port]/... (or
            holds user:password@), a timeout that is not finite, above 0 and at most 3600 s,
            or a key an HTTP header cannot carry. No message repeats the URL or the key.
    """
    if args.parser != "llm":
        return {}
    from language import BackendError, check_api_key, check_timeout, check_url

    if not args.llm_url:
        raise CliError("--parser llm needs --llm-url URL (or WBMP_LLM_URL)", ExitCode.USAGE)
    if not args.llm_model or not args.llm_model.strip():
        raise CliError("--parser llm needs --llm-model NAME (or WBMP_LLM_MODEL)", ExitCode.USAGE)
    # A key copied with a trailing newline or blank is the usual mistake: strip it; a key made
    # only of blanks is no key.
    found = next(((v, os.environ[v].strip()) for v in KEY_VARIABLES if os.environ.get(v, "").strip()), None)
    try:
        url = check_url(args.llm_url, name="--llm-url")
        timeout = check_timeout(args.llm_timeout, name="--llm-timeout")
        key = check_api_key(found[1], name=found[0]) if found else None
    except BackendError as e:
        raise CliError(str(e), ExitCode.USAGE) from None
    return {"url": url, "model": args.llm_model, "api_key": key, "timeout": timeout}


def grounded(plan, scene):
    """``plan`` with each object word's detail naming the scene object it grounds to.

    Raises:
        GroundingError: (exit 3) a reference that names no object of the scene, or several.
    """
    import dataclasses

    from tasks import ground

    words = []
    for w in plan.words:
        if w.role in ("object", "destination", "carried") and w.action is not None:
            param, _, _ = w.detail.partition("=")
            action = plan.actions[w.action - 1]
            value = action.params.get(param)
            if isinstance(value, str):
                obj = ground(value, scene, action=action.name)
                w = dataclasses.replace(w, detail=f"{param}={value} -> scene object '{obj.name}'")
        words.append(w)
    return dataclasses.replace(plan, words=tuple(words))


def _show_clip(text: str, args: argparse.Namespace) -> bool:
    """Print the motion-library clip ``text`` names (as ``wbmp solve --motions`` picks it); False
    when none does."""
    from language import ActionPlan
    from wbmp.motions import clip_dict, clip_words, describe_clip, load_library, match

    clip = match(text, load_library(args.motions))
    if clip is None:
        return False
    words = clip_words(text, clip)
    if args.json:
        print(json.dumps({"actions": [], "backend": args.parser, "clip": clip_dict(clip),
                          "words": [w.to_dict() for w in words]}, ensure_ascii=False))
    else:
        print(describe_clip(clip, args.motions))
        print("words:")
        print(ActionPlan(actions=(), backend=args.parser, text=text, words=words).describe_words())
    return True


def run(args: argparse.Namespace) -> int:
    from language import LanguageError, parse

    text = " ".join(args.text)
    require_instruction(text)  # the bound of `wbmp solve`
    scene = None
    if args.scene is not None:
        from tasks import load_scene

        scene = load_scene(args.scene)
    try:
        plan = parse(text, backend=args.parser, **llm_options(args))
    except LanguageError:
        if not args.motions or not _show_clip(text, args):
            raise  # no clip of the library either: refused as without it
        return ExitCode.OK
    if scene is not None:
        plan = grounded(plan, scene)
    if args.json:
        out = plan.to_dict()
        if plan.words:
            out["words"] = plan.words_dict()
        try:
            line = json.dumps(out, ensure_ascii=False, allow_nan=False)
        except ValueError:  # a NaN/inf that got past the parser: never print invalid JSON
            raise CliError(f"the parsed plan holds a number that is not finite ({text[:80]!r}); "
                           "give finite values", ExitCode.USAGE) from None
        print(line)
    else:
        print(plan.describe())
        if plan.words:
            print("words:")
            print(plan.describe_words())
    return ExitCode.OK
