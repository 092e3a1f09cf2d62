"""Trim a BVH file to a window and a lower frame rate (how the clips of this corpus were made from their sources,
see MANIFEST.yaml):

    python tests/data/teleop/trim.py SOURCE.bvh OUT.bvh --start 0 --duration 4 --rate 60
"""

from __future__ import annotations

import argparse

import numpy as np

from wbcbench.teleop.io.bvh import parse_bvh, write_bvh


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source")
    ap.add_argument("out")
    ap.add_argument("--start", type=float, default=0.0, help="[s]")
    ap.add_argument("--duration", type=float, default=4.0, help="[s]")
    ap.add_argument("--rate", type=float, default=60.0, help="[Hz] (every k-th frame; not above the source's)")
    ap.add_argument("--decimals", type=int, default=4)
    a = ap.parse_args(argv)
    data = parse_bvh(a.source)
    step = max(1, int(round(1.0 / (a.rate * data.frame_time))))
    first = int(round(a.start / data.frame_time))
    last = min(len(data.motion), first + int(round(a.duration / data.frame_time)))
    motion = np.asarray(data.motion[first:last:step])
    write_bvh(a.out, data.skeleton, motion, data.frame_time * step, decimals=a.decimals)
    print(f"{a.out}: {len(motion)} frames at {1.0 / (data.frame_time * step):.4g} Hz")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
