"""`reproduce`: run the paper's matrix in parallel processes and write the report; `report`: the same report
from existing run directories, without simulating.

Output directory:
    report.md, report.html   the paper's tables (ours beside the paper's), fast walk, sanity, figures, runs
    results.json             every number, ours and the paper's (see wbcbench.report.tables)
    figures/*.png            the paper's figures redrawn from our logs
    runs/<section>-<scenario>-<controller>/   the run directories (reproduce only); the tables' cells (paper
                             and fast walk) also hold keyframes.png (a key-frame strip, shown in the report) and,
                             with --video, video.mp4 (linked), rendered in the worker that ran the cell
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing as mp
import os
import queue as queue_mod
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import WbcError
from . import matrix
from .figures import FigureInfo, draw_figures, draw_task, figure_tasks
from .render import to_html, to_markdown
from .runs import ERROR, FELL, MISSING, OK, ReportError, RunOutcome, load_run, read_run_log, run_metrics
from .tables import build_results


@dataclass
class ReportResult:
    """What `reproduce` / `report` wrote.

    Attributes:
        out_dir: the report directory.
        results: the content of results.json.
        outcomes: one per job or run directory.
        figures: figures written.
        errors: one line per run directory that could not be reported (report only).
        wall_time_s: wall time of the whole call [s].
    """

    out_dir: Path
    results: dict
    outcomes: list[RunOutcome]
    figures: list[FigureInfo] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    wall_time_s: float = 0.0


def default_jobs() -> int:
    """Number of cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


# ------------------------------------------------------------------------------------------- workers
_SINK: Callable[[tuple], None] | None = None
"""Where `execute` reports progress: a queue to the parent in a worker process, the progress bar inline."""


def _init_worker(q, plan_cache: str | None = None) -> None:
    global _SINK
    _SINK = q.put_nowait
    if plan_cache:  # the workers share their centroidal plans (planning/centroidal.py)
        from ..planning.centroidal import PLAN_CACHE_ENV
        os.environ[PLAN_CACHE_ENV] = plan_cache


def _send(*msg) -> None:
    if _SINK is not None:
        try:
            _SINK(msg)
        except Exception:  # progress is best effort
            pass


def execute(job: matrix.Job, runs_root: str) -> RunOutcome:
    """Run one job and compute its metrics (in a worker process or inline). Never raises for a run failure."""
    base = dict(section=job.section, controller=job.controller, scenario=job.scenario,
                scenario_run=job.scenario_run, duration_cap_s=job.duration_cap_s)
    if job.missing:
        return RunOutcome(status=MISSING, reason=job.missing, **base)
    from ..runner import run

    run_dir = Path(runs_root) / job.name
    _send("start", job.label)
    try:
        result = run(job.scenario_run, job.controller, job.robot, None, job.duration_cap_s, run_dir,
                     progress=lambda f: _send("progress", job.label, f), sensors=job.sensors, overwrite=True,
                     engine=job.engine, realism=job.realism)
    except WbcError as exc:
        return RunOutcome(status=ERROR, reason=str(exc), run_dir=str(run_dir), **base)
    except Exception as exc:  # a crash outside the controller (the runner keeps controller crashes)
        return RunOutcome(status=ERROR, reason=f"{type(exc).__name__}: {exc}", run_dir=str(run_dir), **base)
    finally:
        _send("done", job.label)
    summary = result.summary
    status, reason = (FELL, summary.get("fall_reason")) if summary.get("fell") else (OK, None)
    if not result.log:
        return RunOutcome(status=ERROR, reason=reason or "no log row written", run_dir=str(run_dir),
                          summary=summary, **base)
    config = json.loads((run_dir / "config.json").read_text())
    try:
        metrics = run_metrics(run_dir, summary, config, result.log)
    except Exception as exc:
        return RunOutcome(status=ERROR, reason=f"metrics failed: {type(exc).__name__}: {exc}",
                          run_dir=str(run_dir), summary=summary, **base)
    outcome = RunOutcome(status=status, reason=reason, run_dir=str(run_dir), summary=summary, metrics=metrics,
                         **base)
    if job.keyframes or job.video:
        render_media(outcome, keyframes=job.keyframes, video=job.video)
    return outcome


KEYFRAMES = 6
"""Key frames per strip in the report."""
KEYFRAME_SIZE = "240x300"
"""Size of one key frame in the report's strips (small: a strip costs little beside its run)."""


def render_media(outcome: RunOutcome, *, keyframes: bool = True, video: bool = False) -> None:
    """Render the run's key-frame strip (RUN_DIR/keyframes.png) and / or video (RUN_DIR/video.mp4, in this
    process) into `outcome`; a failure (e.g. no OpenGL) goes to `outcome.media_error` as one line, never raises."""
    from ..viz.render import keyframe_strip, render_run

    run_dir = Path(outcome.run_dir)
    t0 = time.perf_counter()
    try:
        if keyframes:
            outcome.keyframes = str(keyframe_strip(run_dir, run_dir / "keyframes.png", frames=KEYFRAMES,
                                                   size=KEYFRAME_SIZE))
        if video:
            outcome.video = str(render_run(run_dir, run_dir / "video.mp4", workers=1))
    except Exception as exc:  # the report goes on without the pictures
        msg = str(exc) if isinstance(exc, WbcError) else f"{type(exc).__name__}: {exc}"
        what = "key frames" if keyframes and outcome.keyframes is None else "video"
        outcome.media_error = f"{what} not rendered: {msg.splitlines()[0] if msg else type(exc).__name__}"
    outcome.media_wall_s = time.perf_counter() - t0


# ------------------------------------------------------------------------------------------- execution
def _submission_order(jobs: list[matrix.Job]) -> list[matrix.Job]:
    """The jobs in the order the workers take them: the first cell of each scene first, then the second of each,
    and so on (round robin over the scenes, each scene's cells in their order). The cells of a scene share its
    plan (a multi-contact scene's centroidal plan takes seconds): in the matrix's order, two workers started the
    same scene together and both made its plan; this way each scene's first cell makes it while the other workers
    run other scenes, and its later cells find it made. Every cell runs as before: the order changes no number."""
    groups: dict[tuple, list[matrix.Job]] = {}
    for j in jobs:
        groups.setdefault((j.scenario_run, j.sensors, j.robot, j.engine, j.realism), []).append(j)
    out: list[matrix.Job] = []
    for k in range(max((len(g) for g in groups.values()), default=0)):
        out.extend(g[k] for g in groups.values() if k < len(g))
    return out


def _run_jobs(jobs: list[matrix.Job], runs_root: Path | list[Path], n_jobs: int, progress: bool,
              ray: str | None = None, figures_dir: Path | None = None
              ) -> tuple[list[RunOutcome], list[FigureInfo] | None]:
    """Run `jobs` (into `runs_root`, or one runs root per job) on the process pool, Ray or inline. With
    `figures_dir`, the process pool then draws the report's figures there, in parallel (they took 6 s, serially,
    of a 2-core reproduce's 39): returned in report order; None where they are not drawn (inline, Ray)."""
    global _SINK
    roots = [str(r) for r in runs_root] if isinstance(runs_root, list) else [str(runs_root)] * len(jobs)
    root_of = {id(j): r for j, r in zip(jobs, roots)}
    runnable = _submission_order([j for j in jobs if not j.missing])
    results: dict[int, RunOutcome] = {id(j): execute(j, root_of[id(j)]) for j in jobs if j.missing}
    prog = None
    if progress and runnable:
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        prog = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                        TimeElapsedColumn(), transient=False)
        prog.start()
        total = prog.add_task(f"[bold]reproduce: {len(runnable)} runs on {n_jobs} processes", total=len(runnable))
    tasks: dict[str, int] = {}

    def on_message(msg) -> None:
        if prog is None:
            return
        kind, name = msg[0], msg[1]
        if kind == "start" and name not in tasks:
            tasks[name] = prog.add_task(f"  {name}", total=1.0)
        elif kind == "progress" and name in tasks:
            prog.update(tasks[name], completed=msg[2])
        elif kind == "done" and name in tasks:
            prog.update(tasks[name], completed=1.0, visible=False)

    def finished(job: matrix.Job, outcome: RunOutcome) -> None:
        results[id(job)] = outcome
        if prog is not None:
            prog.advance(total)
            if outcome.status != OK:
                why = f" ({outcome.reason})" if outcome.reason else ""
                prog.console.print(f"  {job.label}: {outcome.status}{why}")

    figures: list[FigureInfo] | None = None
    stack = contextlib.ExitStack()
    try:
        if ray:  # the sweeps' execution layer (wbcbench.study.execute): a local Ray or a cluster
            from ..study.execute import RayExecutor
            with RayExecutor(ray, n_jobs if ray == "auto" else None) as ex:
                kwargs = [{"job": job, "runs_root": root_of[id(job)]} for job in runnable]
                for i, outcome in ex.map_unordered(execute, kwargs):
                    finished(runnable[i], outcome)
        elif n_jobs <= 1:
            _SINK = on_message
            try:
                for job in runnable:
                    finished(job, execute(job, root_of[id(job)]))
            finally:
                _SINK = None
        else:
            ctx = mp.get_context("spawn")
            q = ctx.Queue()
            # the scenes' centroidal plans, made once for the three controllers that start from the same state
            plans = stack.enter_context(tempfile.TemporaryDirectory(prefix="wbcbench-plans-"))
            with ProcessPoolExecutor(max_workers=n_jobs, mp_context=ctx, initializer=_init_worker,
                                     initargs=(q, plans)) as pool:
                pending = {pool.submit(execute, job, root_of[id(job)]): job for job in runnable}
                try:
                    while pending:
                        done, _ = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                        while True:
                            try:
                                on_message(q.get_nowait())
                            except queue_mod.Empty:
                                break
                        for fut in done:
                            job = pending.pop(fut)
                            try:
                                outcome = fut.result()
                            except Exception as exc:  # a worker died (e.g. killed, out of memory)
                                outcome = RunOutcome(job.section, job.controller, job.scenario, ERROR,
                                                     reason=f"worker failed: {type(exc).__name__}: {exc}",
                                                     scenario_run=job.scenario_run,
                                                     duration_cap_s=job.duration_cap_s)
                            finished(job, outcome)
                    if figures_dir is not None:
                        done_runs = [results[id(j)] for j in jobs]
                        futures = [pool.submit(draw_task, t, figures_dir) for t in figure_tasks(done_runs)]
                        try:
                            figures = [f for f in (fut.result() for fut in futures) if f is not None]
                        except Exception:  # (a worker lost: `write_report` draws them in this process)
                            figures = None
                except KeyboardInterrupt:
                    pool.shutdown(wait=False, cancel_futures=True)
                    raise
    finally:
        stack.close()
        if prog is not None:
            prog.stop()
    return [results[id(j)] for j in jobs], figures


def write_report(outcomes: list[RunOutcome], out_dir: str | Path, *, command: str, quick: bool | None = None,
                 jobs: int | None = None, started_at: float | None = None,
                 errors: list[str] | None = None, robot=None,
                 figures: list[FigureInfo] | None = None) -> tuple[dict, list[FigureInfo]]:
    """Write results.json, report.md, report.html and the figures; returns (results, figures).

    `started_at` (a `time.perf_counter()` value) makes results["wall_time_s"] the time since then, figures
    included. `robot` (a `Robot`, None for TALOS): the runs' robot; its report has no published numbers.
    `figures`: the figures drawn already (by `reproduce`'s process pool); None: drawn here.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if figures is None:  # (`reproduce` draws them on its process pool)
        figures = draw_figures(outcomes, out / "figures")
    wall = None if started_at is None else time.perf_counter() - started_at
    results = build_results(outcomes, command=command, quick=quick, jobs=jobs, wall_time_s=wall, errors=errors,
                            robot=robot)
    results["figures"] = [f.file for f in figures]
    results["key_frames"] = key_frames(outcomes, out)
    (out / "results.json").write_text(json.dumps(results, indent=1, allow_nan=False))
    (out / "report.md").write_text(to_markdown(results, figures))
    (out / "report.html").write_text(to_html(results, figures))
    return results, figures


def key_frames(outcomes: list[RunOutcome], out_dir: Path) -> list[dict]:
    """The tables' cells with their key-frame strip and video paths relative to the report directory (a run
    directory given to `report` that holds keyframes.png / video.mp4 counts too), or why they are absent."""
    import os

    out = []
    for o in outcomes:
        if o.section not in matrix.MEDIA_SECTIONS or o.run_dir is None:
            continue
        d = Path(o.run_dir)
        strip = o.keyframes or (str(d / "keyframes.png") if (d / "keyframes.png").is_file() else None)
        video = o.video or (str(d / "video.mp4") if (d / "video.mp4").is_file() else None)
        if strip is None and video is None and o.media_error is None:
            continue
        rel = [None if p is None else Path(os.path.relpath(Path(p).resolve(), out_dir.resolve())).as_posix()
               for p in (strip, video)]
        out.append({"section": o.section, "scenario": o.scenario, "controller": o.controller, "status": o.status,
                    "keyframes": rel[0], "video": rel[1], "error": o.media_error})
    return out


def _plan(*, quick: bool, sanity: bool, sensors: str | None, controllers: list[str] | None,
          scenarios: list[str] | None, keyframes: bool, video: bool, robot: str, engine: str,
          realism: str | None) -> tuple[list[matrix.Job], str, object]:
    """The jobs of one robot's reproduction (every name checked before anything runs), the command line that
    states them and the robot."""
    from .runs import cached_robot

    robot_obj = cached_robot(robot)  # an unknown robot fails before anything runs
    from ..sim.engines import engine_class

    engine_class(engine)  # an unknown or missing engine fails before anything runs
    if realism is not None:  # a bad preset fails before anything runs
        from ..sim.realism import load_realism

        if engine != "mujoco":
            raise WbcError(f"--realism needs the mujoco engine, not '{engine}'")
        load_realism(realism, robot_obj)
    if sensors is not None:
        from ..sensing import load_sensor_profile

        load_sensor_profile(sensors)  # a bad profile fails before anything runs
    if controllers is not None:
        from ..controllers.base import available_controllers, controller_plugin_errors
        from ..errors import UnknownNameError
        from ..plugins import PluginError

        known = available_controllers()
        for c in controllers:
            if c not in known:
                if c in controller_plugin_errors():
                    raise PluginError(controller_plugin_errors()[c], key="--controllers")
                raise UnknownNameError("controller", c, known, key="--controllers")
    plan = matrix.plan_jobs(quick=quick, sanity=sanity, sensors=sensors, controllers=controllers,
                            scenarios=scenarios)
    if keyframes or video:
        from dataclasses import replace

        plan = [replace(j, keyframes=keyframes, video=video) if j.section in matrix.MEDIA_SECTIONS else j
                for j in plan]
    if robot != "talos" or engine != "mujoco" or realism is not None:
        from dataclasses import replace

        plan = [replace(j, robot=robot, engine=engine, realism=realism) for j in plan]
    command = "reproduce --quick" if quick else "reproduce"
    if robot != "talos":
        command += f" --robot {robot}"
    if engine != "mujoco":
        command += f" --engine {engine}"
    if realism is not None:
        command += f" --realism {realism}"
    if sensors:
        command += f" --sensors {sensors}"
    if controllers:
        command += f" --controllers {','.join(controllers)}"
    if scenarios:
        command += f" --scenarios {','.join(scenarios)}"
    if video:
        command += " --video"
    elif not keyframes:
        command += " --no-keyframes"
    return plan, command, robot_obj


def reproduce(out_dir: str | Path, quick: bool = False, jobs: int | None = None, progress: bool = True,
              *, sanity: bool = True, sensors: str | None = None, controllers: list[str] | None = None,
              scenarios: list[str] | None = None, ray: str | None = None, keyframes: bool = True,
              video: bool = False, robot: str = "talos", engine: str = "mujoco",
              realism: str | None = None) -> ReportResult:
    """Run the paper's matrix (and the sanity section) in parallel processes, then write the report.

    Args:
        out_dir: report directory (created); run directories go to out_dir/runs/.
        quick: shorten every walk ("<name>-quick" scenario if it exists, else a duration cap) and the sanity
            runs; see `wbcbench.report.matrix`.
        jobs: number of worker processes (default: the cores this process may use); 1 runs inline.
        progress: show a rich progress bar.
        sanity: also run the standing scenarios with every available controller.
        sensors: a sensor profile (e.g. "talos-like"): the paper's walk, platforms and stairs are run again under
            it, reported beside the ideal runs (section "sensing").
        controllers, scenarios: restrict the matrix to these (`matrix.plan_jobs`); a user's controller is run on
            the paper's scenarios and joins the tables.
        ray: run the cells on Ray ('auto': a local instance with `jobs` CPUs; HOST:PORT: a cluster).
        keyframes: render a key-frame strip of each table cell (paper and fast sections) in the worker that ran
            it, shown in the report; a cell whose rendering fails says why in one line.
        video: also render each table cell's video (RUN_DIR/video.mp4, 1280x720), linked from the report.
        robot: the robot (a profile name or YAML path); another robot than TALOS gets the same report with our
            numbers only (the published ones are TALOS'), its profile's scenario sizes stated.
        engine: the physics engine of every run (`wbcbench.sim.engines`); several engines side by side:
            `reproduce_engines`.
        realism: a realism preset (`wbcbench.sim.realism`) for every run; beside the ideal robot:
            `reproduce_realism`.

    Returns:
        ReportResult; the full run's wall time is in results["wall_time_s"].
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    runs_root = out / "runs"
    runs_root.mkdir(parents=True, exist_ok=True)
    n_jobs = default_jobs() if jobs is None else int(jobs)
    if n_jobs < 1:
        raise WbcError(f"--jobs must be >= 1, got {jobs}")
    plan, command, robot_obj = _plan(quick=quick, sanity=sanity, sensors=sensors, controllers=controllers,
                                     scenarios=scenarios, keyframes=keyframes, video=video, robot=robot,
                                     engine=engine, realism=realism)
    outcomes, figures = _run_jobs(plan, runs_root, n_jobs, progress, ray, figures_dir=out / "figures")
    results, figures = write_report(outcomes, out, command=command, quick=quick, jobs=n_jobs, started_at=t0,
                                    robot=None if robot == "talos" else robot_obj, figures=figures)
    return ReportResult(out, results, outcomes, figures, [], results["wall_time_s"])


def reproduce_engines(out_dir: str | Path, engines: list[str], **kwargs) -> tuple[list[ReportResult], dict]:
    """`reproduce` once per engine (OUT/<engine>/, each a complete report), then the engine-sensitivity section
    (OUT/engine-sensitivity.md, .html, .json: `wbcbench.report.engines`). The first engine is the reference."""
    from ..sim.engines import engine_class
    from . import engines as sensitivity

    if len(engines) < 2 or len(set(engines)) != len(engines):
        raise WbcError(f"--engines needs two or more different engines, got {','.join(engines)}")
    for e in engines:  # every engine checked before anything runs
        engine_class(e)
    out = Path(out_dir)
    reports = [reproduce(out / e, engine=e, **kwargs) for e in engines]
    notes = {e: note for e in engines if (note := getattr(engine_class(e), "COMPARISON_NOTE", None))}
    sens = sensitivity.write({e: r.results for e, r in zip(engines, reports)}, out, notes=notes)
    return reports, sens


def reproduce_realism(out_dir: str | Path, realism: str, posture_gains: bool = True,
                      **kwargs) -> tuple[list[ReportResult], dict]:
    """`reproduce` on the ideal robot (OUT/ideal/) and on the realistic one (OUT/<preset name>/), then the two
    side by side (OUT/real-robot.md, .html, .json): which cells change, which controller falls, the rankings on
    each (paper 000's future work, "evaluate the three controllers on the real robot", as far as simulation
    goes). `posture_gains`: then paper 000's Tables 9-10 on the same preset (`wbcbench.robustness.posture`, when
    the robot has the Table 9 task set), appended to real-robot.md."""
    from ..sim.realism import load_realism
    from . import engines as comparison
    from .runs import cached_robot

    load_realism(realism, cached_robot(kwargs.get("robot", "talos")))  # a bad preset fails before anything runs
    label = Path(str(realism)).stem
    out = Path(out_dir)
    ideal = reproduce(out / "ideal", **kwargs)
    real = reproduce(out / label, realism=realism, **kwargs)
    sens = comparison.write({"ideal": ideal.results, label: real.results}, out, stem="real-robot",
                            title=f"The ideal robot and {label}")
    posture = _posture_section(out, realism, kwargs) if posture_gains else None
    if posture is not None:
        import json

        sens["posture_gains"] = posture
        (out / "real-robot.json").write_text(json.dumps(sens, indent=1, allow_nan=False))
    return [ideal, real], sens


def robot_names(robots: str | list[str]) -> list[str]:
    """`--robots`: "all" (every shipped and installed robot) or names / profile paths, comma-separated or a list."""
    from ..robots.profile import available_robots

    names = robots.split(",") if isinstance(robots, str) else list(robots)
    names = [n.strip() for n in names if n.strip()]
    if names == ["all"]:
        return list(available_robots())
    if not names or len(set(names)) != len(names) or "all" in names:
        raise WbcError(f"--robots needs 'all' or different robot names, got '{','.join(names)}'")
    return names


def reproduce_robots(out_dir: str | Path, robots: str | list[str], *, jobs: int | None = None,
                     progress: bool = True, ray: str | None = None, **kwargs) -> tuple[list[ReportResult], dict]:
    """The matrix on several robots (`robots`: "all" or names, `robot_names`), every robot's cells on one process
    pool; each robot's complete report in OUT/<robot>/ (its runs in OUT/<robot>/runs/), then the cross-robot
    section OUT/robots.md, .html, .json (`wbcbench.report.robots`): each cell's outcome, ZMP error, cost of
    transport and compute time per tick, the 20 cm walk's key frames side by side, and which profile keys were
    generated and which tuned by hand. Every robot is checked before anything runs."""
    from . import robots as section

    t0 = time.perf_counter()
    names = robot_names(robots)
    n_jobs = default_jobs() if jobs is None else int(jobs)
    if n_jobs < 1:
        raise WbcError(f"--jobs must be >= 1, got {jobs}")
    kwargs.setdefault("quick", False)
    kwargs.setdefault("sanity", True)
    opts = dict(sensors=None, controllers=None, scenarios=None, keyframes=True, video=False, engine="mujoco",
                realism=None)
    opts.update({k: kwargs.pop(k) for k in list(kwargs) if k in opts})
    out = Path(out_dir)
    plans = {r: _plan(robot=r, **opts, **kwargs) for r in names}
    jobs_all, roots = [], []
    for r, (plan, _, _) in plans.items():
        jobs_all += plan
        roots += [out / r / "runs"] * len(plan)
        (out / r / "runs").mkdir(parents=True, exist_ok=True)
    outcomes, _ = _run_jobs(jobs_all, roots, n_jobs, progress, ray)
    reports, per_robot, k = [], {}, 0
    for r, (plan, command, robot_obj) in plans.items():
        mine = outcomes[k:k + len(plan)]
        k += len(plan)
        results, figures = write_report(mine, out / r, command=command, quick=kwargs["quick"], jobs=n_jobs,
                                        robot=None if r == "talos" else robot_obj)
        reports.append(ReportResult(out / r, results, mine, figures, [], 0.0))
        per_robot[r] = mine
    provenance = {r: plans[r][2].profile.file for r in names}
    cross = section.write(per_robot, provenance, out, wall_time_s=time.perf_counter() - t0)
    return reports, cross


def _posture_section(out: Path, realism: str, kwargs: dict) -> dict | None:
    """Paper 000's Tables 9-10 (`wbcbench.robustness.posture`) on the same preset, appended to real-robot.md;
    None when the robot has no Table 9 task set (the experiment is TALOS')."""
    from ..controllers.taskset import taskset_variant_path
    from ..robustness.posture import PostureStudy, run_study, write_report
    from .runs import cached_robot

    robot = kwargs.get("robot", "talos")
    if taskset_variant_path(cached_robot(robot), "tsid-torque", "posture") is None:
        return None
    study = PostureStudy(realism=str(realism), robot=robot, iterations=3 if kwargs.get("quick") else 4)
    result = run_study(study, out / "posture-gains", jobs=kwargs.get("jobs"))
    md = write_report(result, out / "posture-gains")
    body = md.read_text().replace("\n## ", "\n### ").replace("# Paper 000", "## Paper 000", 1)
    with open(out / "real-robot.md", "a") as f:
        f.write("\n" + body)
    return {"report": str(md), "table": result["table"], "together": result["together"]}


def report(run_dirs: list[str | Path], out_dir: str | Path) -> ReportResult:
    """Remake the tables and figures from existing run directories, without simulating.

    A run directory that cannot be read (missing or truncated log, missing summary) is left out with a
    one-line error in `ReportResult.errors` (and in the report); the others still report. Runs all of one robot
    other than TALOS report as `reproduce --robot` does (our numbers only).

    Raises:
        ReportError: no run directory given.
    """
    if not run_dirs:
        raise ReportError("no run directory given")
    t0 = time.perf_counter()
    outcomes, errors = [], []
    for d in run_dirs:
        try:
            outcomes.append(load_run(d))
        except ReportError as exc:
            errors.append(str(exc))
    robots = {(o.summary or {}).get("robot", "talos") for o in outcomes}
    robot = None
    if len(robots) == 1 and robots != {"talos"}:  # runs of another robot: our numbers only, as reproduce --robot
        from .runs import cached_robot

        robot = cached_robot(robots.pop())
    results, figures = write_report(outcomes, out_dir, command="report", errors=errors, started_at=t0, robot=robot)
    return ReportResult(Path(out_dir), results, outcomes, figures, errors, results["wall_time_s"])


__all__ = ["ReportResult", "default_jobs", "execute", "key_frames", "read_run_log", "render_media", "report",
           "reproduce", "reproduce_robots", "robot_names", "write_report"]
