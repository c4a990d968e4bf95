"""The benchmark harness of ``wbmp bench`` (the command, ``wbmp/commands/bench.py``, only parses
its options and calls :func:`wbmp.bench.command.run_command`).


For each task class (squat, wave, reach, bow, balance, walk, turn, jump) on one robot:

- parse time (sentence -> actions) and spec build (actions -> TaskSpec), medians over repeats;
- NLP build and solve, first-ever (empty temporary solver cache, nothing in memory), cached
  cold (a new process loading the compiled solver from that cache) and warm (same process);
- IPOPT iterations, the worst constraint violation of the plan's report;
- controller tick median/p99 and simulation real-time factor (MuJoCo, whole-body controller);
- end-to-end wall time of ``wbmp solve`` in a new process (cached solver).

A stage whose layer is missing, or a task class whose primitive the planner cannot plan yet,
is reported as ``n/a (not implemented)``; any other failure of a stage is recorded with its
one-line message and the benchmark goes on. ``--peers`` adds Crocoddyl and TSID figures from
``benchmarks/results/peers/`` (made by ``make bench-peers``) and the ratios ours/peer.
The non-quick run also measures solve time against the horizon length and the robot size,
and draws them (PNG).

Timings are wall-clock [s] unless the key ends in ``_us`` [µs]; see benchmarks/README.md for
the JSON keys.

Exit codes: 0 when every task class that ran passed (one marked ``n/a (not implemented)`` does
not count); otherwise the code ``wbmp solve`` gives, for the first failing task class of the
table: 3 its spec could not be built, 4 its plan failed (infeasible, iteration limit, solver
error), 5 its simulation check failed or crashed (or its end-to-end ``wbmp solve`` exited with
that code). The report is printed, and ``--json``/``--markdown`` written, in every case: a
benchmark whose tasks fail is a failure of the planner or the simulation, not a result to
publish. ``--from`` applies the same rule to the re-read result. Bad options (``--repeats 0``,
``--dt nan``, ``--tasks ""``, an unknown task class, an empty ``--robot``, an output path that
is a folder or a link...) are refused with exit 2 before any work; an unknown robot with 3.
``--max-iterations 1`` makes every plan fail for real (IPOPT stops after one iteration).

Modules: :mod:`~wbmp.bench.tasks` (the task classes, their sentences, specs and JSON keys),
:mod:`~wbmp.bench.options` (option checks, ``--from``), :mod:`~wbmp.bench.machine` (CPU, load,
versions), :mod:`~wbmp.bench.run` (timing runs, repeats, solver caches, scaling study),
:mod:`~wbmp.bench.cold` (the cached-cold child process), :mod:`~wbmp.bench.peers` (Crocoddyl and
TSID results), :mod:`~wbmp.bench.report` (table, Markdown, plot, exit code) and
:mod:`~wbmp.bench.command` (the command from options to exit code). Each name below is imported on
first access.
"""

from __future__ import annotations

from robots import lazy_face

_EXPORTS = {  # public name -> module that defines it
    "NOT_IMPLEMENTED": "wbmp.bench.tasks",
    "QUICK_TASKS": "wbmp.bench.tasks",
    "SCHEMA": "wbmp.bench.tasks",
    "TASKS": "wbmp.bench.tasks",
    "TASK_KEYS": "wbmp.bench.tasks",
    "check_options": "wbmp.bench.options",
    "read_result": "wbmp.bench.options",
    "cpu_model": "wbmp.bench.machine",
    "machine_info": "wbmp.bench.machine",
    "machine_tag": "wbmp.bench.machine",
    "bench_task": "wbmp.bench.run",
    "run_bench": "wbmp.bench.run",
    "scaling_study": "wbmp.bench.run",
    "load_peers": "wbmp.bench.peers",
    "peer_ratios": "wbmp.bench.peers",
    "exit_code": "wbmp.bench.report",
    "format_table": "wbmp.bench.report",
    "markdown_summary": "wbmp.bench.report",
    "plot_scaling": "wbmp.bench.report",
    "task_exit_code": "wbmp.bench.report",
    "run_command": "wbmp.bench.command",
    "_not_implemented": "wbmp.bench.run",  # not public: the tests check the classification
}

__all__ = sorted(name for name in _EXPORTS if not name.startswith("_"))


__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
