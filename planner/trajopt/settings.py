"""Planner settings: four small frozen dataclasses, one per concern, composed into one.

* :class:`SolverSettings`: the NLP solver's options (IPOPT, the transcription, fatrop, the guess);
* :class:`CacheSettings`: where solvers are kept, how they are built (gcc, background builds and
  their memory), the solution library;
* :class:`CollisionSettings`: the self- and scene-collision rows;
* :class:`Tolerances`: what the plan's report accepts;

composed into :class:`PlannerSettings` with the CoM dynamics' own (:class:`CentroidalSettings`) and
the diagnosis switch: ``PlannerSettings(solver=SolverSettings(max_iterations=50),
cache=CacheSettings(compile=True))``; one field changed with ``dataclasses.replace(settings,
cache=dataclasses.replace(settings.cache, compile=False))``.

No default here reads a ``WBMP_*`` switch: a plan depends on its arguments, not on the shell it
runs in (only ``cache_dir`` defaults to ``$WBMP_CACHE_DIR``, :func:`robots.store.cache_base`).
The defaults keep everything in memory (no gcc, no solver written to disk, no stored solution
read); the command line turns the disk cache and the solution library on, as the user's
``WBMP_*`` variables say (:func:`wbmp.environment.planner_settings`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from planner.exceptions import PlannerError
from planner.trajopt.builds import BUILD_MEMORY, MEMORY_MARGIN
from planner.trajopt.centroidal.settings import CentroidalSettings
from robots import cache_base


def default_cache_dir() -> str:
    """``$WBMP_CACHE_DIR``, else ``~/.cache/wbmp`` (:func:`robots.store.cache_base`)."""
    return str(cache_base())


LIBRARY_MODES = ("on", "read", "off")
TRANSCRIPTIONS = ("knots", "stagewise")
STAGEWISE_SOLVERS = ("fatrop", "ipopt")
WARM_STARTS = ("standing", "nominal")


@dataclass(frozen=True, slots=True, kw_only=True)
class SolverSettings:
    """How the NLP is transcribed and solved.

    Attributes:
        max_iterations: IPOPT iteration limit (feasible plans without collision rows need <= 30
            here, a re-solve with new collision or scene rows up to ~110; an infeasible one runs to
            the limit before the diagnosis).
        tolerance: IPOPT convergence tolerance (``tol``) [-].
        constraint_tolerance: IPOPT ``constr_viol_tol`` [constraint units: m, rad].
        print_level: IPOPT print level (0 = silent, 5 = per-iteration table).
        objective_scaling: IPOPT ``obj_scaling_factor``; the costs are small next to the
            constraints, and 1000 cut the Talos squat from 25 to 17 iterations.
        ipopt_extra: Further IPOPT options as ``(name, value)`` pairs, applied last (dynamic
            specs prepend ``centroidal.ipopt_options``).
        warm_start: Initial guess: ``"standing"`` (the standing posture at every knot) or
            ``"nominal"`` (inverse kinematics at the target times, blended: see
            :mod:`planner.trajopt.nominal`).
        transcription: ``"knots"`` (the default: chart displacements per knot, solved by IPOPT,
            :mod:`planner.trajopt.transcription`) or ``"stagewise"`` (positions and velocities as
            states, accelerations as controls, each row on one stage or two neighbours:
            :mod:`planner.trajopt.stagewise`; kinematic plans only, a dynamic spec keeps
            ``"knots"``). Stage-wise solvers are built in memory (never compiled or stored).
        stagewise_solver: The solver of the stage-wise transcription: ``"fatrop"`` (its Riccati
            recursion uses the stage structure) or ``"ipopt"`` (MUMPS on the whole KKT system).
        fatrop_extra: Further fatrop options as ``(name, value)`` pairs, applied last.
    """

    max_iterations: int = 150
    tolerance: float = 1e-6
    constraint_tolerance: float = 1e-7
    print_level: int = 0
    objective_scaling: float = 1000.0
    ipopt_extra: tuple[tuple[str, float | int | str], ...] = ()
    warm_start: str = "nominal"
    transcription: str = "knots"
    stagewise_solver: str = "fatrop"
    fatrop_extra: tuple[tuple[str, float | int | str | bool], ...] = ()

    def __post_init__(self) -> None:
        if self.max_iterations < 1:
            raise PlannerError(f"settings: max_iterations must be >= 1, got {self.max_iterations}")
        if not self.tolerance > 0 or not self.constraint_tolerance > 0:
            raise PlannerError("settings: tolerance and constraint_tolerance must be > 0")
        if self.warm_start not in WARM_STARTS:
            raise PlannerError(f"settings: warm_start must be 'standing' or 'nominal', got {self.warm_start!r}")
        if self.transcription not in TRANSCRIPTIONS:
            raise PlannerError("settings: transcription must be 'knots' or 'stagewise', got "
                               f"{self.transcription!r}")
        if self.stagewise_solver not in STAGEWISE_SOLVERS:
            raise PlannerError("settings: stagewise_solver must be 'fatrop' or 'ipopt', got "
                               f"{self.stagewise_solver!r}")


@dataclass(frozen=True, slots=True, kw_only=True)
class CacheSettings:
    """Where solvers (and stored solutions) are kept and how new solvers are built.

    Attributes:
        use_cache: Reuse solvers in this process and compiled solvers on disk.
        compile: Compile new solvers to C with gcc and store them in ``cache_dir`` (needs
            ``use_cache``). Off (the default; the command line's is on unless ``$WBMP_COMPILE=0``):
            solvers are built in memory only (no gcc, nothing written).
        cache_dir: Directory of the on-disk solver cache (default ``$WBMP_CACHE_DIR`` or
            ``~/.cache/wbmp``).
        compile_flags: gcc flags for generated code (``-O0``: the code is ~3 MB for Talos and
            ``-O1`` takes 4x longer to compile for little solve-time gain).
        compile_timeout: Give up compiling after this long [s] (the plan still runs in memory).
        background_compile: Compile in a detached process and solve this plan with the in-memory
            solver right away; off (the default: a library call leaves no process behind; the
            command line's is on unless ``$WBMP_COMPILE_BACKGROUND=0``): wait for gcc and solve
            with the compiled code (benchmarks of the first-ever build use that).
            Either way at most one build runs per cache folder (:mod:`planner.trajopt.builds`).
        build_memory: Memory one build needs [bytes] (default
            :data:`planner.trajopt.builds.BUILD_MEMORY`, 3.7 GB: gcc -O0 on a Talos solver; the
            command line's ``$WBMP_BUILD_MEMORY``). A build starts only when ``MemAvailable``
            holds it plus ``build_memory_margin``.
        build_memory_margin: Memory a starting build leaves to everything else [bytes]; a running
            compiler is stopped when ``MemAvailable`` falls below half of it.
        compiler: The C compiler of the solver builds (a name on ``PATH`` or a path; called with
            gcc's flags; default ``gcc``; the command line's ``$WBMP_COMPILER``).
        compile_dynamic: Also compile the solvers of dynamic specs (off: their gcc -O0 code takes
            minutes to compile and is not faster than CasADi's virtual machine; they are built
            in memory in a few seconds and stored serialized instead, see ``serialize``).
        serialize: Store new solvers in ``cache_dir`` as serialized CasADi functions instead of
            compiling them (needs ``use_cache``; ignored with ``compile``). Dynamic specs set it
            when ``compile`` is on and ``compile_dynamic`` off: the next process reads the
            solver (~1.2 s of CPU for Talos 4 steps) instead of building it (~3 s).
        solution_library: Earlier solutions of a dynamic plan's solver structure seed its solve
            (:mod:`planner.trajopt.library`): ``"on"`` (use the nearest, store each successful
            plan's), ``"read"`` (use, store nothing), ``"off"`` (every solve from the task's own
            guess: the same result whatever was planned before: the default; the command line's
            is ``$WBMP_SOLUTION_LIBRARY``, else ``"on"``); needs ``use_cache``. Read by
            :func:`planner.plan_with_library` only: :func:`planner.plan` reads no library.
    """

    use_cache: bool = True
    compile: bool = False
    cache_dir: str = field(default_factory=default_cache_dir)
    compile_flags: tuple[str, ...] = ("-O0",)
    compile_timeout: float = 300.0
    background_compile: bool = False
    build_memory: int = BUILD_MEMORY
    build_memory_margin: int = MEMORY_MARGIN
    compiler: str = "gcc"
    compile_dynamic: bool = False
    serialize: bool = False
    solution_library: str = "off"

    def __post_init__(self) -> None:
        if self.build_memory < 0 or self.build_memory_margin < 0:
            raise PlannerError("settings: build_memory and build_memory_margin must be >= 0 bytes, got "
                               f"{self.build_memory} and {self.build_memory_margin}")
        if self.solution_library not in LIBRARY_MODES:
            raise PlannerError("settings: solution_library must be 'on', 'read' or 'off', got "
                               f"{self.solution_library!r}")


@dataclass(frozen=True, slots=True, kw_only=True)
class CollisionSettings:
    """The collision rows (``docs/collisions.md``).

    Attributes:
        self_collision: Keep the links of the robot's collision model apart.
        scene_collision: Keep the robot's sphere sets ``margin`` away from the objects of the
            spec's scene, except in planned contacts.
        margin: Smallest distance between two links' sphere sets, and between a link's sphere set
            and a scene object [m].
        screening: Pairs closer than this on the initial guess get distance rows [m].
        rounds: Re-solves allowed when the solution brings an unscreened pair within the margin
            (each adds its rows and starts from the previous solution).
        warm_rounds: A round's re-solve also starts from the previous solution's multipliers (the
            rows it had keep theirs, the new rows start at zero; IPOPT's warm start, which dynamic
            plans use): g1's retargeted squat re-solved in 16 iterations instead of 46. Off: the
            multipliers start as in a first solve (every plan but a retarget's).
    """

    self_collision: bool = True
    scene_collision: bool = True
    margin: float = 0.01
    screening: float = 0.03
    rounds: int = 3
    warm_rounds: bool = False

    def __post_init__(self) -> None:
        if not 0.0 <= self.margin <= 0.5 or not self.screening >= self.margin:
            raise PlannerError("settings: expected 0 <= collision.margin <= 0.5 m and collision.screening >= "
                               f"collision.margin, got {self.margin:g} and {self.screening:g}")
        if self.rounds < 0:
            raise PlannerError(f"settings: collision.rounds must be >= 0, got {self.rounds}")


@dataclass(frozen=True, slots=True, kw_only=True)
class Tolerances:
    """What the plan's report accepts (the solver's own tolerances are :class:`SolverSettings`').

    Attributes:
        contact: Accepted stance-sole error [m] and [rad].
        limit: Accepted joint-limit violation [rad, rad/s].
        polygon: Accepted CoM excursion outside the shrunk polygon/box [m].
    """

    contact: float = 1e-4
    limit: float = 1e-6
    polygon: float = 1e-5


@dataclass(frozen=True, slots=True, kw_only=True)
class PlannerSettings:
    """How :func:`planner.plan` builds and solves the NLP, one field per concern.

    Attributes:
        solver: The NLP solver's options (:class:`SolverSettings`).
        cache: The solver cache and builds, the solution library (:class:`CacheSettings`).
        collision: The self- and scene-collision rows (:class:`CollisionSettings`).
        tolerances: What the plan's report accepts (:class:`Tolerances`).
        centroidal: Weights and options of the CoM dynamics with contact forces (dynamic specs).
        diagnose: On failure, solve a relaxed problem (hard targets as costs) to name the
            culprit and how far it is.
    """

    solver: SolverSettings = field(default_factory=SolverSettings)
    cache: CacheSettings = field(default_factory=CacheSettings)
    collision: CollisionSettings = field(default_factory=CollisionSettings)
    tolerances: Tolerances = field(default_factory=Tolerances)
    centroidal: CentroidalSettings = field(default_factory=CentroidalSettings)
    diagnose: bool = True
