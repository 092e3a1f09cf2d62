"""`wbcbench render RUN_DIR`: a run's video (MP4) or key-frame strip (PNG)."""

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
