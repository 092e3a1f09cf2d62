"""Branch points: run once up to a time, then continue several times from that same state (`BranchPoint`), each
continuation in a forked child process. `BranchHook` is the run loop's part of it (the ``start`` phase)."""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Callable, Generator
from dataclasses import dataclass
from pathlib import Path
from time import perf_counter

from .errors import ConfigError
from .loop import EndRun, Hook, HookError, RunLoop, Tick

__all__ = ["Branch", "BranchPoint", "BranchHook", "is_branch_child", "branch_exit"]


@dataclass(frozen=True)
class Branch:
    """One continuation of a run from its branch point: its own run directory and the pushes it adds."""

    out: Path
    pushes: tuple = ()


@dataclass(frozen=True)
class BranchPoint:
    """Run once up to time `t`, then continue several times from that same state, each continuation (a
    `Branch`) in a child process of its own (`os.fork`: the simulator, controller, sensing and scenario as they
    are, nothing rebuilt or re-simulated) that writes a complete run directory (log from t = 0, config with its
    pushes, summary) exactly as a run with those pushes from the start would (a branch's pushes must not start
    before `t`).

    `plan()` is a generator: it yields the first `Branch`, is sent the summary of each finished branch (a dict
    with "error" when the branch's process died) and yields the next, until it returns. The branches run one
    after another, so the next can depend on the last (e.g. a bisection over a push's force). The run that
    branches ends at `t`: its own directory keeps the log up to there and its summary counts the branches."""

    t: float
    plan: Callable[[], Generator[Branch, dict, None]]


#: True in a branch's child process (see `BranchPoint`)
_BRANCH_CHILD = False

#: the run directory of this branch's process (see `BranchPoint`)
_BRANCH_DIR: Path | None = None


def is_branch_child() -> bool:
    """Whether this process is a branch's (see `BranchPoint`): it must end with `branch_exit`."""
    return _BRANCH_CHILD


def branch_exit(code: int, error: str | None) -> None:
    """End a branch's process. An error that escaped the run goes to the branch's error.txt (not to a stream
    whose lock another thread of the parent may have held at the fork); nothing of the parent's runs at exit."""
    try:
        if error and _BRANCH_DIR is not None:
            (_BRANCH_DIR / "error.txt").write_text(error)
    finally:
        os._exit(code)


class BranchHook(Hook):
    """At the branch point's tick (``start`` phase): in the parent, every branch runs in its child and the run ends
    there (`EndRun`; ``n_branches`` counts them); in a child, the run goes on as the branch's run."""

    def __init__(self, branch: BranchPoint, config: dict):
        self.branch, self.config = branch, config
        self.k: int | None = None
        self.n_branches = 0

    def begin(self, loop: RunLoop) -> None:
        dt, n = loop.dt, loop.n_ticks
        k = self.k = int(math.floor(self.branch.t / dt + 1e-9))
        if not 0 < k < n:
            raise ConfigError(f"branch point t = {self.branch.t} s outside the run (0, {loop.duration}) s", key="branch")
        if not hasattr(os, "fork"):
            raise ConfigError("branching a run needs os.fork (Linux, macOS)", key="branch")
        rec = loop.recorder
        rec.chunk = max(rec.chunk, k + 1)  # nothing written to the file before the branches: they copy it
        self.loop = loop

    def start(self, s: Tick) -> None:
        if s.k != self.k:
            return
        loop = self.loop
        approach = perf_counter() - loop.wall0
        try:
            got = _branch(self.branch, loop.plant, loop.recorder, self.config)
        except Exception as exc:  # the plan's own error (not the controller's): raised as it is
            raise HookError(exc) from None
        if isinstance(got, int):  # the parent: every branch has run; this run ends here
            self.n_branches = got
            raise EndRun()
        loop.run_dir, loop.wall0 = got, perf_counter() - approach  # a branch: its own run from here on


def _branch(branch: BranchPoint, sim, rec, config: dict) -> Path | int:
    """At the branch point. In the parent, run `branch.plan()`'s branches one by one, each in a forked child,
    and return how many ran. In a child, set up its branch (pushes, run directory and config, log file: the
    rows so far are in memory) and return its run directory: the child then runs on as a normal run and exits
    at the end of `run`."""
    global _BRANCH_CHILD, _BRANCH_DIR
    plan = branch.plan()
    try:
        b = next(plan)
    except StopIteration:
        return 0
    n = 0
    while True:
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            _BRANCH_CHILD = True
            out = _BRANCH_DIR = Path(b.out)
            out.mkdir(parents=True, exist_ok=True)
            for stale in ("summary.json", "error.txt", "log.parquet"):
                (out / stale).unlink(missing_ok=True)
            sim.set_pushes(tuple(sim.pushes) + tuple(b.pushes))
            cfg = {**config, "pushes": [p.__dict__ for p in sim.pushes]}
            (out / "config.json").write_text(json.dumps(cfg, indent=2, default=str))
            rec.path = out / "log.parquet"
            return out
        _, status = os.waitpid(pid, 0)
        n += 1
        code = os.waitstatus_to_exitcode(status)
        try:
            summary = json.loads((Path(b.out) / "summary.json").read_text())
        except (OSError, ValueError):
            why = ""
            try:
                why = ": " + (Path(b.out) / "error.txt").read_text().strip().splitlines()[-1]
            except (OSError, IndexError):
                pass
            summary = {"error": f"the branch's process ended with exit code {code} and no summary{why}"}
        try:
            b = plan.send(summary)
        except StopIteration:
            return n
