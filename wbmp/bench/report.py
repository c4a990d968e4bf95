"""What ``wbmp bench`` shows and concludes: the table, the Markdown summary, the scaling plot (PNG),
and the exit code of a result (:func:`exit_code`, what ``wbmp solve`` gives for the first failing
task class)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from wbmp.bench.tasks import NOT_IMPLEMENTED
from wbmp.errors import CliError, ExitCode


def plot_scaling(scaling: dict[str, Any], path: str | Path, title: str = "") -> Path:
    """Two panels: solve time against N (talos) and against the robot's nv; PNG via Agg."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    hz = [r for r in scaling.get("horizon", []) if r.get("solve_s") is not None]
    ax1.plot([r["knots"] for r in hz], [r["solve_s"] for r in hz], "o-", label="solve (warm)")
    ax1.plot([r["knots"] for r in hz], [r["build_s"] for r in hz], "s--", label="build (first)")
    ax1.set_xlabel("knots N")
    ax1.set_ylabel("time [s]")
    ax1.set_title("talos squat: time vs horizon")
    ax1.set_yscale("log")
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend()
    rb = [r for r in scaling.get("robots", []) if r.get("solve_s") is not None]
    ax2.bar([f"{r['robot']}\nnv={r['nv']}, N={r['knots']}" for r in rb], [r["solve_s"] for r in rb])
    ax2.set_ylabel("solve (warm) [s]")
    ax2.set_title("squat: solve time vs robot")
    ax2.grid(True, axis="y", alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    from viz import atomic_write

    path = Path(path)
    try:
        atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=100))  # never half-written
    finally:
        plt.close(fig)
    return path


def _fmt(x: Any, unit: str = "s", digits: int = 2) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "NO"
    if isinstance(x, float):
        if unit == "ms":
            return f"{1e3 * x:.{digits}f}"
        return f"{x:.{digits}f}"
    return str(x)


def format_table(result: dict[str, Any]) -> str:
    """The human-readable report."""
    m = result["machine"]
    lines = [
        f"wbmp bench on {result['robot']}  ({m['cpu_model']}, {m['cores']} cores, load {m['loadavg'][0]:.1f} "
        f"at start, {result['loadavg_end'][0]:.1f} at end; {result['repeats']} repeat(s); "
        f"{result['date_utc']})",
        "times in s unless noted; first = empty solver cache, cold = new process with the compiled solver on "
        "disk, warm = same process",
        "",
    ]
    head = (f"{'task':8s} {'parse':>6s} {'spec':>6s} {'build':>6s} {'first':>6s} {'cold':>6s} {'warm':>6s} "
            f"{'iter':>4s} {'viol':>9s} {'tick med/p99 [us]':>17s} {'RTF':>5s} {'cert':>4s} {'e2e':>6s}")
    lines += [head, "", "-" * len(head)]
    lines.pop(-2)
    for name, r in result["tasks"].items():
        if r["status"] == NOT_IMPLEMENTED:
            lines.append(f"{name:8s} {NOT_IMPLEMENTED}: {r['message']}"[:160])
            continue
        if r["status"].startswith("failed"):
            lines.append(f"{name:8s} {r['status']}: {r['message']}"[:160])
            continue
        viol = "-" if r["max_violation"] is None else f"{r['max_violation']:.1e}{r['max_violation_unit'] or ''}"
        tick = "-" if r["tick_median_us"] is None else f"{r['tick_median_us']:.0f}/{_fmt(r['tick_p99_us'], digits=0)}"
        lines.append(
            f"{name:8s} {_fmt(r['parse_s'], 'ms'):>6s} {_fmt(r['spec_s'], 'ms'):>6s} {_fmt(r['nlp_build_s']):>6s} "
            f"{_fmt(r['first_total_s']):>6s} {_fmt(r['cold_total_s']):>6s} {_fmt(r['solve_warm_s']):>6s} "
            f"{_fmt(r['iterations']):>4s} {viol:>9s} {tick:>17s} {_fmt(r['realtime_factor']):>5s} "
            f"{_fmt(r['certified']):>4s} {_fmt(r['e2e_s']):>6s}")
        if r["status"] != "ok":
            lines.append(f"{'':8s} ^ {r['status']}: {r['message']}"[:160])
    lines.append("(parse and spec in ms; build = NLP build incl. compilation; first/cold = build + solve; "
                 "warm = solve; RTF = simulated/wall time)")
    if result.get("quick"):
        origins = sorted({r["cache_first"] for r in result["tasks"].values() if r.get("cache_first")})
        lines.append(f"(quick: 'first' is the first plan of this process from the user's solver cache: "
                     f"{'/'.join(origins) or '-'}; run without --quick for first-ever builds)")
    sc = result.get("scaling")
    if sc:
        lines += ["", f"scaling ({sc['sentence']!r}, warm solve):"]
        for r in sc["horizon"]:
            if "error" in r:
                lines.append(f"  talos N={r['knots']:<4d} error: {r['error']}")
            else:
                lines.append(f"  talos N={r['knots']:<4d} solve {r['solve_s']:.2f} s, build {r['build_s']:.1f} s, "
                             f"{r['iterations']} iter, {r['n_variables']} variables")
        for r in sc["robots"]:
            if "error" in r:
                lines.append(f"  {r['robot']:8s} error: {r['error']}")
            else:
                lines.append(f"  {r['robot']:8s} nv={r['nv']:<3d} N={r['knots']:<4d} solve {r['solve_s']:.2f} s, "
                             f"{r['iterations']} iter, {r['n_variables']} variables")
        if result.get("plot"):
            lines.append(f"  plot: {result['plot']}")
    peers = result.get("peers")
    if peers is not None:
        lines += ["", "peers (their own environments; ratio = ours / peer, < 1 means wbmp is faster):"]
        c = peers.get("crocoddyl")
        if c:
            cm = c.get("machine", {})
            lines.append(f"  crocoddyl {c['versions']['crocoddyl']} FDDP (pin {c['versions']['pinocchio']}), "
                         f"measured {cm.get('date_utc', '?')} at load {cm.get('loadavg', ['?'])[0]}")
        t = peers.get("tsid")
        if t:
            lines.append(f"  tsid {t.get('tsid', '?')} (pin {t.get('pin', '?')}): tick median {t['median_us']:.0f} us, "
                         f"p99 {t['p99_us']:.0f} us")
        for name, r in result.get("ratios", {}).items():
            bits = []
            if "crocoddyl_solve_s" in r:
                bits.append(f"crocoddyl solve {r['crocoddyl_solve_s']:.2f} s ({r.get('crocoddyl_iterations')} it)")
                if "warm_over_crocoddyl" in r:
                    bits.append(f"warm/croc {r['warm_over_crocoddyl']:.2f}x")
                if "cold_over_crocoddyl" in r:
                    bits.append(f"cold/croc {r['cold_over_crocoddyl']:.2f}x")
            if "tick_over_tsid" in r:
                bits.append(f"tick/tsid {r['tick_over_tsid']:.2f}x")
            lines.append(f"  {name:8s} " + ", ".join(bits))
        if peers.get("note"):
            lines.append(f"  note: {peers['note']}")
    return "\n".join(lines)


def markdown_summary(result: dict[str, Any]) -> str:
    """A short Markdown table of the run (for the README), with the machine and load."""
    m = result["machine"]
    ratios = result.get("ratios") or {}
    lines = [
        f"{result['robot']}, {m['cpu_model']}, {m['cores']} cores, load average {m['loadavg'][0]:.1f} "
        f"(start) / {result['loadavg_end'][0]:.1f} (end), {result['date_utc'][:10]}, medians of {result['repeats']}:",
        "",
        "| task | first-ever [s] | cached cold [s] | warm solve [s] | iterations | tick median / p99 [µs] | "
        "real-time factor | certified | Crocoddyl FDDP [s] | warm / Crocoddyl |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: |",
    ]
    for name, r in result["tasks"].items():
        if r["status"] == NOT_IMPLEMENTED or r["status"].startswith("failed"):
            lines.append(f"| {name} | {r['status']} | | | | | | | | |")
            continue
        rr = ratios.get(name, {})
        tick = "" if r["tick_median_us"] is None else f"{r['tick_median_us']:.0f} / {_fmt(r['tick_p99_us'], digits=0)}"
        croc = f"{rr['crocoddyl_solve_s']:.2f}" if "crocoddyl_solve_s" in rr else ""
        ratio = f"{rr['warm_over_crocoddyl']:.2f}" if "warm_over_crocoddyl" in rr else ""
        cert = "" if r["certified"] is None else ("yes" if r["certified"] else "no")
        lines.append(f"| {name} | {_fmt(r['first_total_s'])} | {_fmt(r['cold_total_s'])} | {_fmt(r['solve_warm_s'])} "
                     f"| {_fmt(r['iterations'])} | {tick} | {_fmt(r['realtime_factor'])} | {cert} | {croc} | {ratio} |")
    tsid = (result.get("peers") or {}).get("tsid")
    if tsid:
        lines.append("")
        lines.append(f"TSID {tsid.get('tsid', '?')} tick (same controller task, pin {tsid.get('pin', '?')}): "
                     f"median {tsid['median_us']:.0f} µs, p99 {tsid['p99_us']:.0f} µs.")
    return "\n".join(lines) + "\n"


#: Exit code of a task's status (the statuses not listed, "ok" and NOT_IMPLEMENTED, pass).
_STATUS_CODES = {
    "failed at parse/spec": ExitCode.INVALID_SPEC,
    "failed at planner import": ExitCode.INTERNAL,
    "failed at plan": ExitCode.INFEASIBLE,
    "plan failed": ExitCode.INFEASIBLE,
    "simulation failed": ExitCode.SIM_FAILED,
}


def task_exit_code(rec: dict[str, Any]) -> ExitCode:
    """What ``wbmp solve`` would exit with for one task's record (0 = passed or not implemented)."""
    status = rec.get("status")
    if status in _STATUS_CODES:
        return _STATUS_CODES[status]
    if status not in ("ok", NOT_IMPLEMENTED):
        return ExitCode.INTERNAL  # a status this version does not know
    if status == "ok" and rec.get("certified") is False:
        return ExitCode.SIM_FAILED
    e2e = rec.get("e2e_exit_code")
    if status == "ok" and e2e not in (None, 0):
        return ExitCode(e2e) if e2e in ExitCode._value2member_map_ else ExitCode.INTERNAL
    return ExitCode.OK


def exit_code(result: dict[str, Any]) -> ExitCode:
    """0 when every task that ran passed, else the code of the first failing task (module docstring)."""
    for rec in result["tasks"].values():
        code = task_exit_code(rec)
        if code != ExitCode.OK:
            return code
    return ExitCode.OK


def render(result: dict[str, Any], *, markdown: bool, source: str | None) -> tuple[str, str | None]:
    """(table, Markdown or None); a re-read result that cannot be shown is exit 2, not a traceback."""
    try:
        return format_table(result), (markdown_summary(result) if markdown else None)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as e:
        if source is None:
            raise
        raise CliError(f"--from {source!r}: an incomplete or damaged bench result ({type(e).__name__}: "
                       f"{str(e)[:100]})", ExitCode.USAGE) from None

