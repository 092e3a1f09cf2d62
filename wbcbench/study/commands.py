"""CLI: `wbcbench sweep SWEEP.yaml [--jobs N] [--ray ADDRESS|auto] [--out DIR] [--resume] [--yes]` and
`wbcbench sweep-report DIR`."""

from __future__ import annotations

import argparse

COMMANDS = ("sweep", "sweep-report", "tune")


def add_subcommands(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("sweep", help="run a grid / random design of runs (process pool or Ray)")
    s.add_argument("sweep_file", metavar="SWEEP.yaml")
    s.add_argument("--jobs", "-j", type=int, default=1, help="parallel processes, or CPUs of a local Ray (default 1)")
    s.add_argument("--ray", default=None, metavar="ADDRESS|auto",
                   help="run on Ray: 'auto' starts a local instance, HOST:PORT joins a cluster")
    s.add_argument("--out", "-o", default=None, help="sweep directory (default sweeps/<file stem>)")
    s.add_argument("--resume", action="store_true", help="finish a killed sweep (only unfinished cells run)")
    s.add_argument("--yes", "-y", action="store_true", help="allow designs of more than 10,000 cells")
    s.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    r = sub.add_parser("sweep-report", help="tables and plots of a sweep's results.parquet")
    r.add_argument("sweep_dir", metavar="DIR")
    t = sub.add_parser("tune", help="tune task-set gains with Optuna (SQLite study, resumable)")
    t.add_argument("tune_file", metavar="TUNE.yaml")
    t.add_argument("--trials", "-n", type=int, default=30, help="completed trials to reach (default 30)")
    t.add_argument("--jobs", "-j", type=int, default=1, help="parallel trials (process pool, or CPUs of a local Ray)")
    t.add_argument("--ray", default=None, metavar="ADDRESS|auto", help="run trials on Ray")
    t.add_argument("--out", "-o", default=None, help="study directory (default tuning/<file stem>)")
    r.add_argument("--metric", default=None, help="metric column to plot (default: the mean ZMP error if present)")


def _cmd_sweep(args) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, \
        TimeRemainingColumn

    from .execute import make_executor
    from .sweep import run_sweep

    console = Console(stderr=True)
    with make_executor(args.jobs, args.ray) as ex:
        if args.quiet:
            out, table, n = run_sweep(args.sweep_file, args.out, ex, args.resume, args.yes)
        else:
            # the bar starts with the first cell, after the design is validated (errors stay one line)
            prog = Progress(TextColumn("[bold]sweep"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                            TextColumn("ETA"), TimeRemainingColumn(), console=console)
            task = prog.add_task("cells", total=None)

            def on_cell(done: int, total: int, row: dict) -> None:
                if not row:   # the start: ETA from the cells computed now
                    prog.start()
                    prog.update(task, total=total - done, completed=0)
                else:
                    prog.advance(task)

            try:
                out, table, n = run_sweep(args.sweep_file, args.out, ex, args.resume, args.yes, on_cell=on_cell)
            finally:
                prog.stop()
    status = table.column("status").to_pylist() if table.num_rows else []
    print(f"{out}: {table.num_rows} cells ({n} computed now on {ex.name} with {ex.workers} workers): "
          f"{status.count('ok')} ok, {status.count('fell')} fell, {status.count('error')} error -> "
          f"{out / 'results.parquet'}")
    return 0


def run_command(args: argparse.Namespace) -> int:
    if args.command == "sweep":
        return _cmd_sweep(args)
    if args.command == "tune":
        from .execute import make_executor
        from .tune import tune
        with make_executor(args.jobs, args.ray) as ex:
            res = tune(args.tune_file, args.trials, args.out, ex,
                       on_trial=lambda n, total, v: print(f"trial {n}/{total}: "
                                                          f"{'pruned' if v is None else f'{v:.5g}'}", flush=True))
        best = res["best"]
        print(f"{res['out']}: {res['n_trials']} trials; shipped gains {res['baseline']}; best "
              f"{'none' if best is None else best['value']} -> {res['out']}/best-taskset.yaml, report.md")
        return 0
    from .report import sweep_report
    md = sweep_report(args.sweep_dir, metric=args.metric)
    print(md)
    return 0
