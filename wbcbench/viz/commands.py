"""`wbcbench render RUN_DIR`: a run's video (MP4) or key-frame strip (PNG); `wbcbench view RUN_DIR [RUN_DIR ...]`:
the browser 3-D replay (viewer.py); the `--view` options of `run` and `teleop` (live.py)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_subcommand(sub) -> None:
    p = sub.add_parser("render", help="render a run directory to an MP4 video (or a key-frame strip)",
                       description="Replay a run's logged states through MuJoCo's offscreen renderer and encode "
                                   "H.264 MP4 (PyAV), with overlays: planned footholds, CoM and its reference, "
                                   "planned and measured ZMP, contact forces, a caption. Headless (MUJOCO_GL=egl).")
    p.add_argument("run_dir", help="a run directory (log.parquet + config.json)")
    p.add_argument("--out", "-o", default=None, help="output file (default RUN_DIR/video.mp4 or keyframes.png)")
    p.add_argument("--size", default=None, help="WIDTHxHEIGHT (default 1280x720; 320x400 per key frame)")
    p.add_argument("--fps", type=float, default=30.0, help="frames per second of the video (default 30)")
    p.add_argument("--speed", type=float, default=1.0, help="playback speed: 0.5 slow motion, 2 twice as fast")
    p.add_argument("--camera", default="follow", help="follow (default), side, front or top")
    p.add_argument("--no-overlays", action="store_true", help="the robot and the scene only")
    for name in ("footholds", "com", "zmp", "forces", "caption"):
        p.add_argument(f"--no-{name}", action="store_true", help=f"leave out the {name} overlay")
    p.add_argument("--keyframes", type=int, default=0, metavar="N",
                   help="write a PNG strip of N key frames instead of a video")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="render processes feeding the encoder (default 1: one process already uses every core)")
    p.add_argument("--full-meshes", action="store_true",
                   help="draw the visual meshes as loaded (default: simplified copies, 1.5 cm clustering)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress bar")


def add_view_subcommand(sub) -> None:
    p = sub.add_parser("view", help="replay run directories in the browser: 3-D, timeline, overlays, plots",
                       description="Serve a 3-D replay of one or more run directories (viser): the robots' meshes "
                                   "and the terrain, a timeline with play/pause/speed, several runs overlaid as "
                                   "ghosts or side by side, overlay toggles (footholds, CoM, ZMP, contact forces, "
                                   "support polygon, caption) and time plots of log channels. Open the printed "
                                   "address in a browser; Ctrl-C stops.")
    p.add_argument("run_dirs", nargs="+", metavar="RUN_DIR", help="run directories (log.parquet + config.json)")
    p.add_argument("--port", "-p", type=int, default=8080, help="port to serve on (default 8080)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to bind (default 127.0.0.1, this machine only; 0.0.0.0 for every interface)")
    p.add_argument("--layout", default="ghost", help="ghost (overlaid, default) or side (side by side in y)")


def add_view_options(p) -> None:
    """`--view`, `--view-port`, `--view-host` of `wbcbench run` and `wbcbench teleop`."""
    p.add_argument("--view", action="store_true",
                   help="show the robot in the browser while it runs (live view, published at 30 frames/s)")
    p.add_argument("--view-port", type=int, default=8080, help="port of the live view (default 8080)")
    p.add_argument("--view-host", default="127.0.0.1", help="address the live view binds (default 127.0.0.1)")


def live_view_from(args: argparse.Namespace, console=None):
    """The live-view probe the options ask for (None without --view); prints its address."""
    if not getattr(args, "view", False):
        return None
    from .live import LiveView

    view = LiveView(args.view_host, args.view_port, key="--view-port")
    print(f"live view: {view.url}", flush=True)
    return view


def run_view(args: argparse.Namespace) -> int:
    """Serve the replay until Ctrl-C (or SIGTERM); bad input is raised before anything is served."""
    import signal
    import time

    from .viewer import ReplayViewer

    viewer = ReplayViewer(args.run_dirs, host=args.host, port=args.port, layout=args.layout)

    def stop(*_):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        print(f"wbcbench view: {viewer.url} ({len(viewer.replays)} run(s), {viewer.duration:.2f} s); Ctrl-C stops",
              flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        viewer.close()
        signal.signal(signal.SIGTERM, previous)
    return 0


def overlays_from(args: argparse.Namespace):
    from .render import Overlays

    if args.no_overlays:
        return Overlays.none()
    return Overlays(**{name: not getattr(args, f"no_{name}") for name in
                       ("footholds", "com", "zmp", "forces", "caption")})


def run_command(args: argparse.Namespace) -> int:
    from rich.console import Console

    from .render import keyframe_strip, render_run

    console = Console(stderr=True)
    overlays = overlays_from(args)
    cell = {"mesh_cell": 0.0} if args.full_meshes else {}
    if args.keyframes:
        out = keyframe_strip(args.run_dir, args.out, frames=args.keyframes, size=args.size or "320x400",
                             camera=args.camera, overlays=overlays, **cell)
        print(out)
        return 0
    kwargs = dict(size=args.size or "1280x720", fps=args.fps, speed=args.speed, camera=args.camera,
                  overlays=overlays, workers=args.workers, **cell)
    if args.quiet:
        out = render_run(args.run_dir, args.out, **kwargs)
    else:
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        with Progress(TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                      TimeElapsedColumn(), console=console, transient=True) as prog:
            task = prog.add_task(f"render {Path(args.run_dir).name}", total=1.0)
            out = render_run(args.run_dir, args.out, progress=lambda f: prog.update(task, completed=f), **kwargs)
    print(out)
    return 0
