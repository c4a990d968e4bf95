"""PNG plots of a plan (and its simulation): balance, joint limits, torques, forces, keyframes.

Matplotlib's Agg canvas draws into figures created directly (no ``pyplot`` state, no display);
each file is written atomically. :func:`write_plots` returns the paths it wrote:

- ``com_support.png``: top view of the CoM (and ZMP for dynamic plans) over the support
  polygons, CoM/ZMP x and y against the polygon's extent, and the signed distance to the
  polygon edge over time.
- ``joints.png``: every joint's position and velocity as a fraction of its limits over time, and
  the worst fraction per joint.
- ``torques.png`` (when simulated): torque as a fraction of the limit, over time and per joint.
- ``contact_forces.png`` (dynamic plan or simulation): normal force and friction use per contact.
- ``keyframes.png``: side and front stick figures of the robot at a few instants.
"""

from __future__ import annotations

import contextvars
import os
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")  # no display; harmless when already set

import numpy as np
import pinocchio as pin
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon as PolygonPatch

from robots import Robot
from viz import motion as vm

if TYPE_CHECKING:
    from sim.execution import Execution
from viz.files import Staging, atomic_write

DPI = 100
PLAN_COLOR = "#c1121f"
ZMP_COLOR = "#1d4ed8"
SIM_COLOR = "#2a9d8f"
SUPPORT_FACE = "#9bd3a8"
SUPPORT_EDGE = "#1b7a3a"
MAX_SAMPLES = 2000  # points per line for simulated (1 kHz) signals
PLOT_FILES = ("com_support.png", "joints.png", "torques.png", "contact_forces.png", "keyframes.png", "objects.png")
"""Every file name :func:`write_plots` may write (which ones depends on the plan)."""

# the Staging of the write_plots call drawing in this thread/task (None: _save writes at once)
_STAGING: contextvars.ContextVar[Staging | None] = contextvars.ContextVar("wbmp_plot_staging", default=None)


def _save(fig: Figure, path: Path) -> Path:
    FigureCanvasAgg(fig)

    def write(fh) -> None:
        fig.savefig(fh, dpi=DPI, format="png")

    staging = _STAGING.get()
    if staging is not None:
        return staging.add(path, write)
    return atomic_write(path, write)


def _is_dynamic(plan) -> bool:
    return bool(plan.forces) or bool(getattr(plan.spec, "dynamic", False))


def plot_com_support(path: Path, robot: Robot, plan, *, simulated: vm.Motion | None = None) -> Path:
    """CoM (and ZMP when dynamic) against the support polygon; see the module docstring."""
    t = np.asarray(plan.t, dtype=float)
    com = np.asarray(plan.com, dtype=float)
    phases = vm.support_phases(robot, plan)
    dynamic = _is_dynamic(plan)
    zmp = vm.zmp_from_com(t, com) if dynamic else None
    sim_t = sim_com = None
    if simulated is not None:
        step = max(1, len(simulated.t) // 400)
        sim_t = simulated.t[::step]
        sim_com = vm.com_trajectory(robot, simulated.q[::step])

    fig = Figure(figsize=(15, 5.2))
    ax_top, ax_xy, ax_margin = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.1, 1.3, 1.3]})
    for ph in phases:
        if len(ph.polygon) >= 3:
            ax_top.add_patch(PolygonPatch(ph.polygon, closed=True, facecolor=SUPPORT_FACE, alpha=0.35,
                                          edgecolor=SUPPORT_EDGE, lw=1.0))
        for corners in ph.soles.values():
            ax_top.add_patch(PolygonPatch(corners[:, :2], closed=True, fill=False, edgecolor="#555", lw=0.8))
    _draw_scene_top(ax_top, getattr(plan.spec, "scene", None))
    ax_top.plot(com[:, 0], com[:, 1], color=PLAN_COLOR, lw=2, label="CoM (plan)")
    ax_top.plot(com[0, 0], com[0, 1], "o", color=PLAN_COLOR, ms=5)
    if zmp is not None:
        ax_top.plot(zmp[:, 0], zmp[:, 1], "--", color=ZMP_COLOR, lw=1.5, label="ZMP (plan)")
    if sim_com is not None:
        ax_top.plot(sim_com[:, 0], sim_com[:, 1], ":", color=SIM_COLOR, lw=2, label="CoM (simulated)")
    ax_top.set_aspect("equal", adjustable="datalim")
    ax_top.set_xlabel("x [m]")
    ax_top.set_ylabel("y [m]")
    ax_top.set_title("top view: CoM over the support polygon")
    ax_top.legend(loc="best", fontsize=8)
    ax_top.grid(alpha=0.3)

    for axis, name, style in ((0, "x", "-"), (1, "y", "-")):
        ax_xy.plot(t, com[:, axis], style, lw=2, label=f"CoM {name}",
                   color=PLAN_COLOR if axis == 0 else "#e76f51")
        if zmp is not None:
            ax_xy.plot(t, zmp[:, axis], "--", lw=1.2, label=f"ZMP {name}",
                       color=ZMP_COLOR if axis == 0 else "#4895ef")
    for ph in phases:
        if len(ph.polygon) >= 3:
            for axis, color in ((0, PLAN_COLOR), (1, "#e76f51")):
                lo, hi = ph.polygon[:, axis].min(), ph.polygon[:, axis].max()
                ax_xy.fill_between([ph.start, ph.end], [lo, lo], [hi, hi], color=color, alpha=0.08, lw=0)
                ax_xy.hlines([lo, hi], ph.start, ph.end, colors=color, linestyles=":", lw=0.8)
    ax_xy.set_xlabel("t [s]")
    ax_xy.set_ylabel("[m]")
    ax_xy.set_title("CoM x, y and the support polygon's extent")
    ax_xy.legend(loc="best", fontsize=8)
    ax_xy.grid(alpha=0.3)

    def margins(times: np.ndarray, xy: np.ndarray) -> np.ndarray:
        out = np.full(len(times), np.nan)
        for i, (ti, p) in enumerate(zip(times, xy, strict=True)):
            ph = phases[plan.spec.phase_at(float(ti))]
            if len(ph.polygon) >= 3 and np.all(np.isfinite(p)):
                out[i] = vm.point_in_polygon_margin(p, ph.polygon)
        return out

    ax_margin.plot(t, margins(t, com[:, :2]), lw=2, color=PLAN_COLOR, label="CoM (plan)")
    if zmp is not None:
        ax_margin.plot(t, margins(t, zmp), "--", lw=1.5, color=ZMP_COLOR, label="ZMP (plan)")
    if sim_t is not None and sim_com is not None:
        ax_margin.plot(sim_t - sim_t[0], margins(sim_t - sim_t[0], sim_com[:, :2]), ":", lw=2,
                       color=SIM_COLOR, label="CoM (simulated)")
    required = [b.margin for b in plan.spec.com_bounds if b.support_polygon]
    ax_margin.axhline(0.0, color="k", lw=1)
    if required:
        ax_margin.axhline(max(required), color=SUPPORT_EDGE, ls=":", lw=1,
                          label=f"required margin {max(required):.3f} m")
    for ph in phases:
        ax_margin.axvline(ph.start, color="#999", lw=0.5)
    ax_margin.set_xlabel("t [s]")
    ax_margin.set_ylabel("distance inside the polygon [m] (< 0: outside)")
    ax_margin.set_title("margin to the support polygon edge")
    ax_margin.legend(loc="best", fontsize=8)
    ax_margin.grid(alpha=0.3)
    fig.suptitle(_title(robot, plan), fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def _draw_scene_top(ax, scene_data) -> None:
    """Each scene object's footprint (seen from above) in its colour, with its name (``gid`` =
    ``scene/<name>``, so a test can find the patch)."""
    if scene_data is None:
        return
    from viz.scene import footprint

    for obj in scene_data.objects:
        outline = footprint(obj)
        if outline is None or len(outline) < 3:
            continue
        r, g, b, _ = (float(c) for c in obj.colour)
        patch = PolygonPatch(outline, closed=True, facecolor=(r, g, b), alpha=0.45, edgecolor=(r * 0.6, g * 0.6, b * 0.6),
                             lw=1.0, hatch="//")
        patch.set_gid(f"scene/{obj.name}")
        ax.add_patch(patch)
        centre = outline.mean(axis=0)
        ax.text(float(centre[0]), float(centre[1]), obj.name, ha="center", va="center", fontsize=7, color="#333")


def _title(robot: Robot, plan) -> str:
    name = plan.spec.description or plan.spec.name or "plan"
    return f"{name}  ({robot.name}, {float(plan.t[-1]):.2f} s)"


def _revolute_joints(robot: Robot) -> list[tuple[str, int, int]]:
    """(name, idx_q, idx_v) of every one-dof actuated joint."""
    out = []
    model = robot.model
    for j in range(2, model.njoints):
        jm = model.joints[j]
        if jm.nq == 1 and jm.nv == 1:
            out.append((model.names[j], jm.idx_q, jm.idx_v))
    return out


def _fractions(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Position within [lo, hi] mapped to [-1, 1] around the middle (|x| = 1 at a limit)."""
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (values - mid) / half
    out[:, ~np.isfinite(half) | (half <= 0)] = 0.0
    return out


def _worst_labels(ax, t: np.ndarray, series: np.ndarray, names: list[str], n: int = 5) -> None:
    worst = np.argsort(-np.nanmax(np.abs(series), axis=0))[:n]
    for k in worst:
        ax.plot(t, series[:, k], lw=1.6, label=names[k])
    ax.legend(loc="lower left", fontsize=7, ncol=2)


def plot_joints(path: Path, robot: Robot, plan) -> Path:
    """Joint positions and velocities against their limits; see the module docstring."""
    t = np.asarray(plan.t, dtype=float)
    joints = _revolute_joints(robot)
    names = [j[0] for j in joints]
    iq = np.array([j[1] for j in joints], dtype=int)
    iv = np.array([j[2] for j in joints], dtype=int)
    q = np.asarray(plan.q, dtype=float)[:, iq]
    pos = _fractions(q, robot.lower_limits[iq], robot.upper_limits[iq])
    vmax = robot.velocity_limits[iv]
    if plan.v is not None and len(plan.v):
        v = np.asarray(plan.v, dtype=float)[:, iv]
    else:
        v = np.gradient(q, t, axis=0) if len(t) > 1 else np.zeros_like(q)
    with np.errstate(divide="ignore", invalid="ignore"):
        vel = np.where(np.isfinite(vmax) & (vmax > 0), v / vmax, 0.0)

    fig = Figure(figsize=(15, max(6.0, 0.16 * len(names) + 1.5)))
    gs = fig.add_gridspec(2, 2, width_ratios=[1.6, 1.0])
    ax_p, ax_v, ax_bar = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[:, 1])
    for ax, series in ((ax_p, pos), (ax_v, vel)):
        ax.plot(t, series, color="#bbb", lw=0.7)
        _worst_labels(ax, t, series, names)
        for lim in (-1.0, 1.0):
            ax.axhline(lim, color="k", lw=1.2, ls="--")
        ax.set_ylim(-1.15, 1.15)
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
    ax_p.set_ylabel("position in range [-1 = lower, +1 = upper]")
    ax_p.set_title("joint positions against their limits (5 closest labelled)")
    ax_v.set_ylabel("velocity / limit")
    ax_v.set_title("joint velocities against their limits")
    worst_p = np.abs(pos).max(axis=0)
    worst_v = np.abs(vel).max(axis=0)
    y = np.arange(len(names))
    ax_bar.barh(y - 0.2, worst_p, height=0.4, color="#457b9d", label="position")
    ax_bar.barh(y + 0.2, worst_v, height=0.4, color="#e76f51", label="velocity")
    ax_bar.axvline(1.0, color="k", lw=1.2, ls="--")
    ax_bar.set_yticks(y, names, fontsize=7)
    ax_bar.invert_yaxis()
    ax_bar.set_xlim(0, max(1.1, float(np.nanmax([worst_p.max(initial=0), worst_v.max(initial=0)])) * 1.05))
    ax_bar.set_xlabel("worst |fraction of the limit| (1 = at the limit)")
    ax_bar.set_title("worst use of each joint's range")
    ax_bar.legend(loc="lower right", fontsize=8)
    ax_bar.grid(alpha=0.3, axis="x")
    fig.suptitle(_title(robot, plan), fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def plot_torques(path: Path, robot: Robot, plan, simulated: vm.Motion) -> Path:
    """Simulated torques against the limits."""
    assert simulated.tau is not None  # drawn only for a run that recorded its torques
    joints = _revolute_joints(robot)
    names = [j[0] for j in joints]
    iv = np.array([j[2] for j in joints], dtype=int) - 6
    step = max(1, len(simulated.tau) // MAX_SAMPLES)  # 1 kHz simulations: plot <= MAX_SAMPLES points
    tau = np.asarray(simulated.tau, dtype=float)[::step, iv]
    t = (simulated.t - simulated.t[0])[::step][: len(tau)]
    lim = robot.torque_limits[iv]
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(lim > 0, tau / lim, 0.0)
    fig = Figure(figsize=(15, max(6.0, 0.16 * len(names) + 1.5)))
    ax_t, ax_bar = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.6, 1.0]})
    ax_t.plot(t, frac, color="#bbb", lw=0.6)
    _worst_labels(ax_t, t, frac, names)
    for lim_line in (-1.0, 1.0):
        ax_t.axhline(lim_line, color="k", lw=1.2, ls="--")
    ax_t.set_xlabel("t [s]")
    ax_t.set_ylabel("torque / limit")
    ax_t.set_title("simulated joint torques against their limits (5 largest labelled)")
    ax_t.grid(alpha=0.3)
    worst = np.abs(frac).max(axis=0)
    y = np.arange(len(names))
    ax_bar.barh(y, worst, color=["#c1121f" if w > 1 else "#457b9d" for w in worst])
    ax_bar.axvline(1.0, color="k", lw=1.2, ls="--")
    ax_bar.set_yticks(y, names, fontsize=7)
    ax_bar.invert_yaxis()
    ax_bar.set_xlabel("worst |torque| / limit")
    ax_bar.set_title("peak torque per joint")
    ax_bar.grid(alpha=0.3, axis="x")
    fig.suptitle(_title(robot, plan), fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def plot_contact_forces(path: Path, robot: Robot, plan, simulated: vm.Motion | None) -> Path | None:
    """Normal force and friction use per contact, planned and/or simulated."""
    series = []
    if plan.forces:
        series.append(("plan", np.asarray(plan.t, dtype=float), plan.forces, "--"))
    if simulated is not None and simulated.forces:
        step = max(1, len(simulated.t) // MAX_SAMPLES)
        series.append(("simulated", (simulated.t - simulated.t[0])[::step],
                       {k: np.asarray(f)[::step] for k, f in simulated.forces.items()}, "-"))
    if not series:
        return None
    mu = robot.profile.friction_coefficient
    fig = Figure(figsize=(13, 6.5))
    ax_n, ax_f = fig.subplots(2, 1, sharex=True)
    colors = ["#1d4ed8", "#c1121f", "#2a9d8f", "#f4a261", "#6a4c93", "#555"]
    frames = sorted({f for _, _, forces, _ in series for f in forces})
    for label, t, forces, style in series:
        for frame, f in forces.items():
            f = np.asarray(f, dtype=float)
            n = min(len(t), len(f))
            color = colors[frames.index(frame) % len(colors)]
            fn = f[:n, 2]
            ft = np.linalg.norm(f[:n, :2], axis=1)
            ax_n.plot(t[:n], fn, style, color=color, lw=1.2, label=f"{frame} ({label})")
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(fn > 1.0, ft / fn, np.nan)
            ax_f.plot(t[:n], ratio, style, color=color, lw=1.0, label=f"{frame} ({label})")
    weight = robot.mass * vm.GRAVITY
    ax_n.axhline(weight, color="k", ls="--", lw=1, label=f"body weight {weight:.0f} N")
    ax_n.set_ylabel("normal force [N]")
    ax_n.set_title("contact forces")
    ax_n.legend(loc="best", fontsize=8)
    ax_n.grid(alpha=0.3)
    ax_f.axhline(mu, color="k", ls="--", lw=1, label=f"friction coefficient {mu:.2f}")
    ax_f.set_ylabel("|tangential| / normal")
    ax_f.set_xlabel("t [s]")
    ax_f.legend(loc="best", fontsize=8)
    ax_f.grid(alpha=0.3)
    fig.suptitle(_title(robot, plan), fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def skeleton_segments(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Line segments (S, 2, 3) of a stick figure at ``q``: parent joint -> child joint, plus the
    hands, feet and head frames [m]."""
    model, data = robot.model, robot.data()
    pin.framesForwardKinematics(model, data, q)
    segs = []
    for j in range(2, model.njoints):
        parent = model.parents[j]
        segs.append((data.oMi[parent].translation.copy(), data.oMi[j].translation.copy()))
    for role in ("left_hand", "right_hand", "left_foot", "right_foot", "head"):
        if robot.has_role(role):
            fid = robot.frame_id(role)
            j = model.frames[fid].parentJoint
            segs.append((data.oMi[j].translation.copy(), data.oMf[fid].translation.copy()))
    return np.array(segs)


def plot_keyframes(path: Path, robot: Robot, plan, *, count: int = 6) -> Path:
    """Side (x-z) and front (y-z) stick figures at ``count`` evenly spaced instants."""
    t = np.asarray(plan.t, dtype=float)
    ks = np.unique(np.linspace(0, len(t) - 1, min(count, len(t))).round().astype(int))
    q = np.asarray(plan.q, dtype=float)
    h = robot.height()
    spacing = 0.9 * h
    fig = Figure(figsize=(2.3 * len(ks) + 1, 7.5))
    ax_side, ax_front = fig.subplots(2, 1)
    phases = vm.support_phases(robot, plan)
    data = robot.data()
    for col, k in enumerate(ks):
        segs = skeleton_segments(robot, q[k])
        com = pin.centerOfMass(robot.model, data, q[k])
        ph = phases[plan.spec.phase_at(float(t[k]))]
        for ax, (a, b) in ((ax_side, (0, 2)), (ax_front, (1, 2))):
            off = col * spacing - (q[k, a] if a < 2 else 0.0)
            for p0, p1 in segs:
                ax.plot([p0[a] + off, p1[a] + off], [p0[b], p1[b]], color="#264653", lw=1.6,
                        solid_capstyle="round")
            ax.plot(com[a] + off, com[b], "o", color=PLAN_COLOR, ms=6)
            ax.plot([com[a] + off] * 2, [0.0, com[b]], ":", color=PLAN_COLOR, lw=0.8)
            for corners in ph.soles.values():
                lo, hi = corners[:, a].min() + off, corners[:, a].max() + off
                ax.plot([lo, hi], [0.0, 0.0], color=SUPPORT_EDGE, lw=4, solid_capstyle="butt")
            ax.text(col * spacing, -0.08 * h, f"t = {t[k]:.2f} s", ha="center", va="top", fontsize=9)
    for ax, title in ((ax_side, "side view (x forward, z up)"), (ax_front, "front view (y left, z up)")):
        ax.axhline(0.0, color="#888", lw=1)
        ax.set_aspect("equal")
        ax.set_ylim(-0.15 * h, 1.08 * h)
        ax.set_xlim(-0.5 * spacing, (len(ks) - 0.5) * spacing)
        ax.set_xticks([])
        ax.set_ylabel("z [m]")
        ax.set_title(title, fontsize=10)
    fig.suptitle(_title(robot, plan) + "  -  red: centre of mass, green: contact soles", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def write_plots(directory: str | os.PathLike, robot: Robot, plan, *, execution: Execution | None = None,
                staging: Staging | None = None) -> list[Path]:
    """Write the PNG plots of ``plan`` (and of ``execution`` when given) into ``directory``.

    Args:
        directory: Output folder (created if missing).
        robot: The robot.
        plan: A :class:`planner.Plan`.
        execution: Optional simulated execution (a :class:`sim.Execution`).
        staging: Stage the files there (renamed into place by ``staging.commit()``, together
            with the command's other outputs) instead of writing them now (:mod:`viz.files`);
            the folder is then created at the commit.

    Returns:
        The files written (or staged), in the order of :data:`PLOT_FILES`.

    Raises:
        VizInputError: the plan or execution arrays do not match the robot.
    """
    out = Path(directory)
    vm.plan_motion(robot, plan)  # shape checks
    simulated = vm.execution_motion(robot, execution)
    if staging is None:
        with Staging() as own:
            paths = write_plots(out, robot, plan, execution=execution, staging=own)
            own.commit()
        return paths
    token = _STAGING.set(staging)
    try:
        return _draw_all(out, robot, plan, simulated)
    finally:
        _STAGING.reset(token)


def plot_objects(path: Path, robot: Robot, plan, t: np.ndarray, objects) -> Path | None:
    """The simulated height of each object a grasp of the plan holds, against the asked lift over
    its hold window (docs/objects.md); None when the plan holds none that was simulated.

    Args:
        t: Simulated times (T',) [s].
        objects: Object name -> its pose (T', 7) or centre position (T', 3) [m] (column 2 is the height).
    """
    grasps = [g for g in getattr(plan.spec, "grasps", ()) if g.object in objects]
    if not grasps:
        return None
    fig = Figure(figsize=(10, 4.5))
    ax = fig.subplots()
    for g in grasps:
        z = np.asarray(objects[g.object], dtype=float)[:, 2]
        tt = np.asarray(t, dtype=float)[: len(z)]
        line = ax.plot(tt, z, lw=1.5, label=f"{g.object} (simulated)")[0]
        if g.hold is not None and g.lift > 0:
            ax.hlines(z[0] + g.lift, g.hold[0], g.hold[1], colors=line.get_color(), linestyles="--",
                      label=f"{g.object}: asked lift {g.lift:g} m")
            ax.axvspan(g.hold[0], g.hold[1], color=line.get_color(), alpha=0.08)
        ax.axvline(g.start, color=line.get_color(), lw=0.8, ls=":")
        if g.end is not None:
            ax.axvline(g.end, color=line.get_color(), lw=0.8, ls=":")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("object centre height [m]")
    ax.set_title("held objects: height (dotted: grasp and release; shaded: hold window)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.suptitle(_title(robot, plan), fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def _draw_all(out: Path, robot: Robot, plan, simulated: vm.Motion | None) -> list[Path]:
    paths = [plot_com_support(out / "com_support.png", robot, plan, simulated=simulated),
             plot_joints(out / "joints.png", robot, plan)]
    if simulated is not None and simulated.tau is not None:
        paths.append(plot_torques(out / "torques.png", robot, plan, simulated))
    forces = plot_contact_forces(out / "contact_forces.png", robot, plan, simulated)
    if forces is not None:
        paths.append(forces)
    paths.append(plot_keyframes(out / "keyframes.png", robot, plan))
    if simulated is not None and simulated.objects:
        drawn = plot_objects(out / "objects.png", robot, plan, simulated.t, simulated.objects)
        if drawn is not None:
            paths.append(drawn)
    return paths
