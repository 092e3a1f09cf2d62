"""The paper's figures (4-9) redrawn from our run logs, plus one figure per sanity scenario.

matplotlib without pyplot (an Agg canvas per figure): no global backend state, safe in worker processes.
A figure whose runs are missing is not drawn; `draw_figures` returns only the figures it wrote.
"""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..metrics.from_log import (FOOT_REF_CHANNELS, XYZ, configuration, foot_kinematics, ft_contact_wrenches,
                                ground_height, measured_zmp)
from ..metrics.energy import STANDARD_GRAVITY
from ..side import Side
from .paper import CONTROLLER_LABELS, CONTROLLERS, SCENARIO_LABELS
from .runs import FELL, RunOutcome, cached_robot, read_run_log

COLORS = {"ik": "tab:blue", "tsid-position": "tab:orange", "tsid-torque": "tab:green", "joint-pd": "tab:red"}
OTHER_COLORS = ("tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


@dataclass(frozen=True)
class FigureInfo:
    """A figure written to disk: file name (relative to the report directory), title and caption."""

    file: str
    title: str
    caption: str


class _Logs:
    """Logs and robots of the runs, read once."""

    def __init__(self) -> None:
        self._logs: dict[str, dict | None] = {}

    def get(self, o: RunOutcome) -> tuple[dict, object] | None:
        if not o.run_dir or not o.has_metrics:
            return None
        if o.run_dir not in self._logs:
            try:
                self._logs[o.run_dir] = read_run_log(o.run_dir)
            except Exception:
                self._logs[o.run_dir] = None
        log = self._logs[o.run_dir]
        if log is None:
            return None
        cfg_path = Path(o.run_dir) / "config.json"
        cfg = json.loads(cfg_path.read_text()) if cfg_path.is_file() else {}
        robot = cached_robot(str(cfg.get("robot_profile") or o.summary.get("robot") or "talos"))
        return log, robot


def _color(controller: str) -> str:
    """A controller's line colour: its own, or one of the others chosen by its name (a checksum, the same in every
    process: Python's `hash` of a string changes from one process to the next)."""
    if controller in COLORS:
        return COLORS[controller]
    return OTHER_COLORS[zlib.crc32(controller.encode()) % len(OTHER_COLORS)]


def _label(o: RunOutcome) -> str:
    name = CONTROLLER_LABELS.get(o.controller, o.controller)
    if o.controller not in CONTROLLER_LABELS and o.summary.get("mode"):
        name += f" ({o.summary['mode']})"
    return f"{name} (fell)" if o.status == FELL else name


def _order(outcomes: list[RunOutcome]) -> list[RunOutcome]:
    rank = {c: i for i, c in enumerate(CONTROLLERS)}
    return sorted(outcomes, key=lambda o: (rank.get(o.controller, len(rank)), o.controller))


def _new(rows: int, height: float = 2.6) -> tuple[Figure, list]:
    fig = Figure(figsize=(9, height * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    return fig, list(axes)


def _save(fig: Figure, out_dir: Path, name: str) -> str:
    fig.savefig(out_dir / name, dpi=110)
    return name


def _ref(logs: _Logs, runs: list[RunOutcome], cols: list[str]) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, values) of a reference channel from the first run that logged it with finite values."""
    for o in runs:
        got = logs.get(o)
        if got is None:
            continue
        log, _ = got
        if all(c in log for c in cols):
            v = np.column_stack([log[c] for c in cols])
            if np.isfinite(v).any():
                return log["t"], v
    return None


def zmp_figure(logs: _Logs, runs: list[RunOutcome], out_dir: Path, name: str, title: str) -> str | None:
    """ZMP from the ankle F/T sensors per axis (x top, y bottom), one line per controller, and the reference."""
    fig, (ax_x, ax_y) = _new(2)
    drawn = False
    for o in _order(runs):
        got = logs.get(o)
        if got is None:
            continue
        log, robot = got
        zmp = measured_zmp(log, robot)
        if zmp is None:
            continue
        for ax, j in ((ax_x, 0), (ax_y, 1)):
            ax.plot(log["t"], zmp[:, j], color=_color(o.controller), lw=0.9, label=_label(o))
        drawn = True
    if not drawn:
        return None
    ref = _ref(logs, runs, ["zmp_ref.x", "zmp_ref.y"])
    if ref is not None:
        for ax, j in ((ax_x, 0), (ax_y, 1)):
            ax.plot(ref[0], ref[1][:, j], "k--", lw=1.0, label="reference")
    ax_x.set_ylabel("ZMP x [m]")
    ax_y.set_ylabel("ZMP y [m]")
    ax_y.set_xlabel("time [s]")
    for ax in (ax_x, ax_y):
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.suptitle(title)
    return _save(fig, out_dir, name)


def left_force_figure(logs: _Logs, runs: list[RunOutcome], out_dir: Path, name: str, title: str) -> str | None:
    """Vertical ground force on the left foot from its ankle F/T sensor (foot weight removed)."""
    fig, (ax,) = _new(1, 3.2)
    drawn = False
    for o in _order(runs):
        got = logs.get(o)
        if got is None:
            continue
        log, robot = got
        w = ft_contact_wrenches(log, robot)
        if w is None:
            continue
        ax.plot(log["t"], w[Side.LEFT].force[:, 2], color=_color(o.controller), lw=0.9, label=_label(o))
        drawn = True
    if not drawn:
        return None
    ax.set_ylabel("left foot force z [N]")
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.suptitle(title)
    return _save(fig, out_dir, name)


def walk_state_figure(logs: _Logs, run: RunOutcome, out_dir: Path, name: str, title: str) -> str | None:
    """Feet, CoM, DCM and ZMP per axis for one run (paper Figure 6); references dashed."""
    got = logs.get(run)
    if got is None:
        return None
    log, robot = got
    kin = foot_kinematics(log, robot)
    if kin is None:
        return None
    t = log["t"]
    com = np.column_stack([log[f"com.{a}"] for a in XYZ])
    vcom = np.column_stack([log[f"com_vel.{a}"] for a in XYZ])
    height = com[:, 2] - ground_height(log, kin)
    with np.errstate(invalid="ignore", divide="ignore"):
        omega = np.sqrt(STANDARD_GRAVITY / np.where(height > 0, height, np.nan))
        dcm = com + vcom / omega[:, None]
    zmp = measured_zmp(log, robot, kin)
    fig, axes = _new(2, 3.2)
    for ax, j, axis in ((axes[0], 0, "x"), (axes[1], 1, "y")):
        ax.plot(t, kin.p_world_sole[Side.LEFT][:, j], color="tab:blue", lw=1, label="left foot")
        ax.plot(t, kin.p_world_sole[Side.RIGHT][:, j], color="tab:red", lw=1, label="right foot")
        ax.plot(t, com[:, j], color="tab:green", lw=1.2, label="CoM")
        ax.plot(t, dcm[:, j], color="tab:purple", lw=0.8, label="DCM")
        if zmp is not None:
            ax.plot(t, zmp[:, j], color="tab:orange", lw=0.6, alpha=0.8, label="ZMP (F/T)")
        foot_refs = [(f"{name}_{s.value}.{axis}", color, f"{s.value} foot ref")
                     for name in FOOT_REF_CHANNELS if f"{name}_left.{axis}" in log
                     for s, color in ((Side.LEFT, "tab:blue"), (Side.RIGHT, "tab:red"))][:2]
        for col, color, label in (*foot_refs, (f"com_ref.{axis}", "tab:green", "CoM ref"),
                                  (f"zmp_ref.{axis}", "tab:orange", "ZMP ref")):
            if col in log and np.isfinite(log[col]).any():
                ax.plot(t, log[col], color=color, ls="--", lw=0.9, label=label)
        ax.set_ylabel(f"{axis} [m]")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=7, ncol=2)
    axes[1].set_xlabel("time [s]")
    fig.suptitle(title)
    return _save(fig, out_dir, name)


def angular_momentum_figure(logs: _Logs, run: RunOutcome, out_dir: Path, name: str, title: str) -> str | None:
    """Centroidal angular momentum per axis (paper Figure 7), from the logged q and v (ground truth)."""
    got = logs.get(run)
    if got is None:
        return None
    log, robot = got
    q = configuration(log, robot)
    vcols = [f"v.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")] + [f"v.{j}" for j in robot.joint_names]
    if q is None or any(c not in log for c in vcols):
        return None
    v = np.column_stack([log[c] for c in vcols])
    model, data = robot.model, robot.model.createData()
    am = np.full((q.shape[0], 3), np.nan)
    for k in np.flatnonzero(np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(v), axis=1)):
        qk = q[k].copy()
        qk[3:7] /= np.linalg.norm(qk[3:7])
        am[k] = pin.computeCentroidalMomentum(model, data, qk, v[k]).angular
    fig, axes = _new(3, 2.2)
    for ax, j, axis in zip(axes, range(3), XYZ, strict=True):
        ax.plot(log["t"], am[:, j], color=_color(run.controller), lw=0.9, label=_label(run))
        ax.set_ylabel(f"L_{axis} [kg m^2/s]")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    return _save(fig, out_dir, name)


def sanity_figure(logs: _Logs, runs: list[RunOutcome], out_dir: Path, name: str, title: str) -> str | None:
    """CoM y (reference dashed) and F/T ZMP y per controller for a standing scenario."""
    fig, (ax_c, ax_z) = _new(2)
    drawn = False
    for o in _order(runs):
        got = logs.get(o)
        if got is None:
            continue
        log, robot = got
        c = _color(o.controller)
        ax_c.plot(log["t"], log["com.y"], color=c, lw=1, label=_label(o))
        zmp = measured_zmp(log, robot)
        if zmp is not None:
            ax_z.plot(log["t"], zmp[:, 1], color=c, lw=0.8, label=_label(o))
        drawn = True
    if not drawn:
        return None
    ref = _ref(logs, runs, ["com_ref.y"])
    if ref is not None:
        ax_c.plot(ref[0], ref[1][:, 0], "k--", lw=1, label="CoM reference")
    ax_c.set_ylabel("CoM y [m]")
    ax_z.set_ylabel("ZMP y (F/T) [m]")
    ax_z.set_xlabel("time [s]")
    for ax in (ax_c, ax_z):
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.suptitle(title)
    return _save(fig, out_dir, name)


@dataclass(frozen=True)
class FigureTask:
    """One figure to draw: `draw` (the name of one of this module's figure functions), its runs (a single
    outcome for the functions of one run), its file name, the plot's title, and the report's title and caption.
    Picklable: a worker process can draw it (`draw_task`)."""

    draw: str
    runs: tuple[RunOutcome, ...]
    file: str
    plot_title: str
    title: str
    caption: str


_ONE_RUN = ("walk_state_figure", "angular_momentum_figure")


def figure_tasks(outcomes: list[RunOutcome]) -> list[FigureTask]:
    """Every figure the report may show, in report order (a figure whose runs drew nothing is left out later)."""

    def runs(scenario: str) -> tuple[RunOutcome, ...]:
        return tuple(o for o in outcomes if o.scenario == scenario and o.has_metrics)

    tasks: list[FigureTask] = []
    for scen, fig_no in (("walk-20cm", 4), ("walk-20cm-fast", None), ("platforms", 8), ("stairs", 9)):
        label = SCENARIO_LABELS.get(scen, scen)
        tag = f"Figure {fig_no}" if fig_no else "Extra figure"
        tasks.append(FigureTask("zmp_figure", runs(scen), f"zmp_{scen}.png", f"ZMP estimation, {label}",
                                f"{tag}: ZMP estimation, {label}",
                                "ZMP from the two ankle F/T sensors (foot mass removed), x top, y bottom; dashed: "
                                "planned ZMP."))
        if scen == "walk-20cm":
            tasks.append(FigureTask("left_force_figure", runs(scen), "left_foot_force_walk-20cm.png",
                                    "Left foot vertical force, 20 cm walk", "Figure 5: Z-axis left foot force, 20 cm walk",
                                    "Vertical ground force on the left foot from its ankle F/T sensor, foot weight "
                                    "removed."))
    for o in runs("walk-60cm"):
        if o.controller != "tsid-torque":
            continue
        tasks.append(FigureTask("walk_state_figure", (o,), "walk_state_walk-60cm.png",
                                "Feet, CoM, DCM and ZMP, 60 cm walk",
                                "Figure 6: Feet, CoM, DCM and ZMP, 60 cm walk (TSID torque)",
                                "Measured (solid) and planned (dashed); feet are the sole origins by forward kinematics, "
                                "the DCM c + c_dot / omega with omega = sqrt(g / (c_z - ground))."))
        tasks.append(FigureTask("angular_momentum_figure", (o,), "angular_momentum_walk-60cm.png",
                                "Centroidal angular momentum, 60 cm walk",
                                "Figure 7: Angular momentum, 60 cm walk (TSID torque)",
                                "Centroidal angular momentum about the CoM, world axes, computed from the logged q "
                                "and v."))
    for scen in sorted({o.scenario for o in outcomes if o.section == "sanity"}):
        tasks.append(FigureTask("sanity_figure", runs(scen), f"sanity_{scen}.png", f"Sanity: {scen}",
                                f"Sanity: {scen}",
                                "CoM y (dashed: reference) and ZMP y from the ankle F/T sensors per controller."))
    return tasks


def draw_task(task: FigureTask, out_dir: str | Path, logs: _Logs | None = None) -> FigureInfo | None:
    """Draw one figure into `out_dir` (in this or a worker process); None where its runs drew nothing."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fn = globals()[task.draw]
    what = task.runs[0] if task.draw in _ONE_RUN else list(task.runs)
    file = fn(logs if logs is not None else _Logs(), what, out, task.file, task.plot_title)
    return FigureInfo(f"{out.name}/{file}", task.title, task.caption) if file else None


def draw_figures(outcomes: list[RunOutcome], out_dir: str | Path) -> list[FigureInfo]:
    """Write every figure that has data into `out_dir`; returns them in report order."""
    logs = _Logs()  # the runs' logs read once for every figure
    return [f for t in figure_tasks(outcomes) if (f := draw_task(t, out_dir, logs)) is not None]
