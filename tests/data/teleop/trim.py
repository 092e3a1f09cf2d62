"""Trim a BVH, C3D or TRC file to a window and a lower frame rate (how the clips of this corpus were made from their
sources, see MANIFEST.yaml):

    python tests/data/teleop/trim.py SOURCE.bvh OUT.bvh --start 0 --duration 4 --rate 60
    python tests/data/teleop/trim.py SOURCE.c3d OUT.c3d --start 10.5 --duration 3 --rate 60

A C3D file keeps its labelled markers (subject prefix and all; unlabelled ``*N`` markers are dropped, and those
whose label matches ``--drop``, a regular expression, such as a modelling software's output points) in its own
``POINT:UNITS``; a gap (negative residual) stays a gap (NaN). Its analog channels, force plates and events are
not copied. A TRC file keeps its markers, written in millimetres (``--decimals`` of a millimetre); a gap stays an
empty cell.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

from wbcbench.teleop.io.bvh import parse_bvh, write_bvh


def _window(n: int, frame_time: float, a) -> slice:
    step = max(1, int(round(1.0 / (a.rate * frame_time))))
    first = int(round(a.start / frame_time))
    last = min(n, first + int(round(a.duration / frame_time)))
    return slice(first, last, step)


def trim_c3d(a) -> str:
    import ezc3d

    from wbcbench.teleop.io.c3d import write_c3d

    c = ezc3d.c3d(a.source, extract_forceplat_data=False)
    point = c["parameters"]["POINT"]
    labels = [str(s).strip() for s in point["LABELS"]["value"]]
    units = str(point["UNITS"]["value"][0]).strip().lower()
    rate = float(np.asarray(point["RATE"]["value"]).ravel()[0])
    xyz = np.transpose(np.asarray(c["data"]["points"], dtype=float)[:3], (2, 1, 0))  # (N, P, 3) in `units`
    residuals = np.asarray(c["data"]["meta_points"]["residuals"])[0].T  # (N, P)
    xyz[residuals < 0] = np.nan
    w = _window(xyz.shape[0], 1.0 / rate, a)
    scale = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}[units]
    markers = {lab: np.round(xyz[w, k], a.decimals) * scale for k, lab in enumerate(labels)
               if lab and not lab.startswith("*") and not (a.drop and re.fullmatch(a.drop, lab))}
    write_c3d(a.out, markers, rate / w.step, units=units)
    return f"{a.out}: {len(next(iter(markers.values())))} frames of {len(markers)} markers at {rate / w.step:.4g} Hz"


def trim_trc(a) -> str:
    from wbcbench.teleop.io.trc import read_trc_markers, write_trc

    labels, xyz, rate = read_trc_markers(a.source)
    w = _window(xyz.shape[0], 1.0 / rate, a)
    markers = {lab: np.round(xyz[w, k] * 1e3, a.decimals) * 1e-3 for k, lab in enumerate(labels)}
    write_trc(a.out, markers, rate / w.step, units="mm", decimals=a.decimals)
    return f"{a.out}: {len(xyz[w])} frames of {len(markers)} markers at {rate / w.step:.4g} Hz"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source")
    ap.add_argument("out")
    ap.add_argument("--start", type=float, default=0.0, help="[s]")
    ap.add_argument("--duration", type=float, default=4.0, help="[s]")
    ap.add_argument("--rate", type=float, default=60.0, help="[Hz] (every k-th frame; not above the source's)")
    ap.add_argument("--decimals", type=int, default=4, help="BVH: decimals kept; C3D: of the file's unit; TRC: of a mm")
    ap.add_argument("--drop", default="", help="C3D: a regular expression; the labels it matches are not copied")
    a = ap.parse_args(argv)
    if Path(a.source).suffix.lower() == ".c3d":
        print(trim_c3d(a))
        return 0
    if Path(a.source).suffix.lower() == ".trc":
        print(trim_trc(a))
        return 0
    data = parse_bvh(a.source)
    w = _window(len(data.motion), data.frame_time, a)
    motion = np.asarray(data.motion[w])
    write_bvh(a.out, data.skeleton, motion, data.frame_time * w.step, decimals=a.decimals)
    print(f"{a.out}: {len(motion)} frames at {1.0 / (data.frame_time * w.step):.4g} Hz")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
