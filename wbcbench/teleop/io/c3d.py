"""C3D marker files (Vicon, Qualisys, OptiTrack exports) through ``ezc3d``: Plug-in Gait markers -> the segment
poses of the retargeting's canonical segments.

Markers are matched by label, case-insensitive, a subject prefix (``Name:LASI``) dropped. The full-body Plug-in
Gait set is needed (``LWRB``/``RWRB``, ``LFIN``/``RFIN``, ``LTHI``, ``LTIB``, ``LHEE`` are optional)::

    head    LFHD RFHD LBHD RBHD            thorax  C7 T10 CLAV STRN
    pelvis  LASI RASI and LPSI RPSI or SACR
    arms    LSHO LELB LWRA (LWRB LFIN), and R...
    legs    LKNE LANK LTOE, and R...

Segment origins, in the marker data's frame (positions converted to metres from ``POINT:UNITS``):

* Pelvis: the mid-point of the ASIS; pelvis frame y from RASI to LASI, x from the PSIS (or SACR) mid-point
  towards the ASIS one, made orthogonal; hip joint centres by Harrington et al. (2007, J. Biomech. 40:595)
  from the pelvis width PW (ASIS distance) and depth PD: x = -0.24 PD - 9.9 mm, y = +-(0.33 PW + 7.3 mm),
  z = -0.30 PW - 10.9 mm;
* T8: the centroid of C7, T10, CLAV and STRN; Neck: the mid-point of C7 and CLAV; thorax up: from the T10/STRN
  mid-point to the C7/CLAV one;
* Head: the centroid of the four head markers, 10 cm down the head frame (x from the back markers to the front
  ones, y from right to left); the head's orientation is that frame;
* shoulder centre: SHO 5 cm down the thorax; wrist centre: WRA/WRB mid-point (WRA if WRB is missing); elbow,
  knee and ankle centres: the lateral marker moved medially by half a typical joint width plus a marker
  radius (elbow 4.2 cm, knee 5.7 cm, ankle 4.2 cm), perpendicular to the proximal segment (Plug-in Gait's
  chord function, without the subject's measured widths);
* hands: origin the wrist centre, y from the finger marker to the wrist (else along the forearm), x from the
  thumb-side to the little-finger-side wrist marker made orthogonal; other segments: z along the segment,
  y the body's left made orthogonal.

Other full-body sets are read through :data:`MARKER_ALIASES`: the Vicon set of the CMU and HDM05 databases has
its pelvis markers on a waist belt (front and back waist, ``LFWT`` ``RFWT`` ``LBWT`` ``RBWT``) where Plug-in Gait
has the ASIS and PSIS; they stand in for them (the belt sits a few centimetres above and outside the iliac spines,
so the hip joint centres come out that much higher and wider). OpenSim's gait marker set (its Gait2354/Gait2392
examples: ``R.ASIS`` ``V.Sacral`` ``R.Acromium`` ``R.Elbow`` ``R.Wrist.Lat``/``.Med`` ``R.Knee.Lat``/``.Med``
``R.Ankle.Lat``/``.Med`` ``R.Toe.Tip`` ``Sternum``) names the same landmarks otherwise, and has no C7, T10, CLAV
or four head markers:

* thorax from ``Sternum`` and the acromia: Neck at the acromion mid-point, T8 half-way to the sternum marker,
  thorax up from the pelvis centre (ASIS and sacrum mid-points) to the Neck (so it leans with the lumbar spine);
* head from ``R.Temple`` ``L.Temple`` ``Top.Head``: y from the right temple to the left one, z from the temples'
  mid-point towards the head top marker (made orthogonal); the origin 20 cm below the head top along z (the
  temple markers sit forward of the head's centre: the head top, on the vertex, is above it);
* a medial knee or ankle marker (``KNM``/``MED``, the Conventional Gait Model 2's labels) puts the joint centre
  half-way between it and the lateral one instead of the chord offset.

:func:`marker_set` names the set a file's labels follow.

A marker's gap (no data, or a negative residual) is NaN: the segments built from it are invalid in that frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import ConfigError
from .. import _rotations as rot
from .recording import MocapRecording

__all__ = ["C3D_REQUIRED", "MARKER_ALIASES", "marker_set", "markers_recording", "read_c3d", "write_c3d"]

#: markers a C3D file must label (the pelvis also needs LPSI+RPSI or SACR)
C3D_REQUIRED = ("LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10", "CLAV", "STRN", "LASI", "RASI",
                "LSHO", "LELB", "LWRA", "RSHO", "RELB", "RWRA", "LKNE", "LANK", "LTOE", "RKNE", "RANK", "RTOE")
#: the thorax's and the head's markers: Plug-in Gait's, else OpenSim's gait set (after :data:`MARKER_ALIASES`)
_THORAX_SETS = (("C7", "T10", "CLAV", "STRN"), ("STRN", "LSHO", "RSHO"))
_HEAD_SETS = (("LFHD", "RFHD", "LBHD", "RBHD"), ("L.TEMPLE", "R.TEMPLE", "TOP.HEAD"))
_OPENSIM_GAIT = "OpenSim gait (Gait2354)"
#: Plug-in Gait label -> the labels other marker sets give the same landmark (the first present is used): the
#: CMU / HDM05 Vicon set's waist belt markers for the ASIS and PSIS; OpenSim's gait set (upper case)
MARKER_ALIASES = {"LASI": ("LFWT", "L.ASIS"), "RASI": ("RFWT", "R.ASIS"), "LPSI": ("LBWT",), "RPSI": ("RBWT",),
                  "SACR": ("V.SACRAL",), "STRN": ("STERNUM",),
                  **{f"{s}{pig}": (f"{s}.{osim}",) for s in "LR" for pig, osim in (
                      ("SHO", "ACROMIUM"), ("ELB", "ELBOW"), ("WRA", "WRIST.LAT"), ("WRB", "WRIST.MED"),
                      ("KNE", "KNEE.LAT"), ("KNM", "KNEE.MED"), ("ANK", "ANKLE.LAT"), ("MED", "ANKLE.MED"),
                      ("TOE", "TOE.TIP"))}}
#: an alias label -> the marker set that uses it (for :func:`marker_set`)
_ALIAS_SETS = {"LFWT": "Vicon waist (CMU, HDM05)", "RFWT": "Vicon waist (CMU, HDM05)",
               "L.ASIS": _OPENSIM_GAIT, "R.ASIS": _OPENSIM_GAIT}
_UNITS = {"mm": 1e-3, "cm": 1e-2, "dm": 0.1, "m": 1.0, "in": 0.0254}
_R_ELBOW, _R_KNEE, _R_ANKLE, _SHOULDER_DROP, _HEAD_DROP = 0.042, 0.057, 0.042, 0.05, 0.10
_PARENTS = {"Pelvis": None, "T8": "Pelvis", "Neck": "T8", "Head": "Neck",
            "LeftUpperArm": "T8", "LeftForeArm": "LeftUpperArm", "LeftHand": "LeftForeArm",
            "RightUpperArm": "T8", "RightForeArm": "RightUpperArm", "RightHand": "RightForeArm",
            "LeftUpperLeg": "Pelvis", "LeftLowerLeg": "LeftUpperLeg", "LeftFoot": "LeftLowerLeg",
            "LeftToe": "LeftFoot",
            "RightUpperLeg": "Pelvis", "RightLowerLeg": "RightUpperLeg", "RightFoot": "RightLowerLeg",
            "RightToe": "RightFoot"}


def _ezc3d(file: str):
    try:
        import ezc3d
    except ImportError:
        raise ConfigError("reading C3D needs ezc3d: pip install 'wbcbench[c3d]'", file=file) from None
    return ezc3d


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def _perp(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """v without its component along the unit vectors `axis` (both (N, 3))."""
    return v - np.sum(v * axis, axis=-1, keepdims=True) * axis


def _frame(x_hint: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations with y along `y` and x the component of `x_hint` orthogonal to it."""
    y = _unit(y)
    x = _unit(_perp(x_hint, y))
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def _frame_z(z: np.ndarray, y_hint: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations with z along `z` and y the component of `y_hint` orthogonal to it."""
    z = _unit(z)
    y = _unit(_perp(y_hint, z))
    return np.stack([np.cross(y, z), y, z], axis=-1)


def _medial(lateral: np.ndarray, proximal: np.ndarray, towards: np.ndarray, radius: float) -> np.ndarray:
    """A joint centre: the lateral marker moved by `radius` towards `towards`, perpendicular to the proximal
    segment (from the marker to `proximal`)."""
    axis = _unit(proximal - lateral)
    return lateral + radius * _unit(_perp(towards - lateral, axis))


def marker_set(labels) -> str:
    """The marker set upper-case `labels` (subject prefixes dropped) follow: "Plug-in Gait" when its ASIS markers
    are there, else the set whose alias labels stand in for them (:data:`MARKER_ALIASES`), else "unknown"."""
    labels = set(labels)
    if {"LASI", "RASI"} <= labels:
        return "Plug-in Gait"
    for alias, name in _ALIAS_SETS.items():
        if alias in labels:
            return name
    return "unknown"


def with_aliases(m: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """`m` with each missing Plug-in Gait label filled from its first present alias (:data:`MARKER_ALIASES`)."""
    out = dict(m)
    for label, aliases in MARKER_ALIASES.items():
        if label not in out:
            found = next((a for a in aliases if a in out), None)
            if found is not None:
                out[label] = out[found]
    return out


def segments_from_markers(m: dict[str, np.ndarray], file: str = "") -> tuple[dict, dict]:
    """(segment -> (N, 3) origin, segment -> (N, 3, 3) orientation) from Plug-in Gait markers (module docstring);
    `m`: marker label (upper case) -> (N, 3) positions [m]; labels of other marker sets are read through
    :data:`MARKER_ALIASES`."""
    m = with_aliases(m)
    sets = {}
    missing = [k + "".join(f"/{a}" for a in MARKER_ALIASES.get(k, ())) for k in C3D_REQUIRED
               if k not in m and k not in _THORAX_SETS[0] + _HEAD_SETS[0]]  # the thorax and head: below
    if not ("SACR" in m or ("LPSI" in m and "RPSI" in m)):
        missing.append("LPSI+RPSI or SACR")
    for part, options in (("thorax", _THORAX_SETS), ("head", _HEAD_SETS)):
        sets[part] = next((k for k, o in enumerate(options) if all(label in m for label in o)), None)
        if sets[part] is None:
            missing.append(" or ".join("+".join(o) for o in options))
    if missing:
        raise ConfigError(f"markers {missing} not found (labels: {', '.join(sorted(m)[:12])}"
                          f"{', ...' if len(m) > 12 else ''}); a full-body set is needed: Plug-in Gait, the CMU/HDM05 "
                          "Vicon waist set or OpenSim's gait set",
                          file=file or None)
    asis = 0.5 * (m["LASI"] + m["RASI"])
    back = m["SACR"] if "SACR" in m else 0.5 * (m["LPSI"] + m["RPSI"])
    R_pelvis = _frame(asis - back, m["LASI"] - m["RASI"])  # y left; x forward; z up
    pw = np.linalg.norm(m["LASI"] - m["RASI"], axis=-1)
    pd = np.linalg.norm(asis - back, axis=-1)
    x, y, z = (R_pelvis[..., k] for k in range(3))
    pos: dict[str, np.ndarray] = {"Pelvis": asis}
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        pos[f"{side}UpperLeg"] = (asis + ((-0.24 * pd - 0.0099)[:, None] * x)
                                  + (sign * (0.33 * pw + 0.0073))[:, None] * y + (-0.30 * pw - 0.0109)[:, None] * z)
    if sets["thorax"] == 0:
        top, bottom = 0.5 * (m["C7"] + m["CLAV"]), 0.5 * (m["T10"] + m["STRN"])
        pos["T8"] = 0.25 * (m["C7"] + m["T10"] + m["CLAV"] + m["STRN"])
    else:  # the acromia and the sternum marker (OpenSim's gait set)
        top, bottom = 0.5 * (m["LSHO"] + m["RSHO"]), 0.5 * (asis + back)
        pos["T8"] = 0.5 * (top + m["STRN"])
    up = _unit(top - bottom)
    pos["Neck"] = top
    if sets["head"] == 0:
        front, rear = 0.5 * (m["LFHD"] + m["RFHD"]), 0.5 * (m["LBHD"] + m["RBHD"])
        R_head = _frame(front - rear, 0.5 * (m["LFHD"] + m["LBHD"]) - 0.5 * (m["RFHD"] + m["RBHD"]))
        head_x, head_left = R_head[..., 0], R_head[..., 1]
        head_up = np.cross(head_x, head_left)
        head_centre = 0.25 * (m["LFHD"] + m["RFHD"] + m["LBHD"] + m["RBHD"])
    else:  # two temples and the head top (OpenSim's gait set)
        temples = 0.5 * (m["L.TEMPLE"] + m["R.TEMPLE"])
        R_head = _frame_z(m["TOP.HEAD"] - temples, m["L.TEMPLE"] - m["R.TEMPLE"])
        head_x, head_up = R_head[..., 0], R_head[..., 2]
        head_centre = m["TOP.HEAD"] - _HEAD_DROP * head_up  # the head band's level, 10 cm below the vertex
    pos["Head"] = head_centre - _HEAD_DROP * head_up
    rots: dict[str, np.ndarray] = {"Pelvis": R_pelvis,
                                   "Head": np.stack([head_x, head_up, np.cross(head_x, head_up)], axis=-1)}
    left = y
    for side, s in (("Left", "L"), ("Right", "R")):
        other = "R" if s == "L" else "L"
        shoulder = m[f"{s}SHO"] - _SHOULDER_DROP * up
        wrist = 0.5 * (m[f"{s}WRA"] + m[f"{s}WRB"]) if f"{s}WRB" in m else m[f"{s}WRA"]
        elbow = _medial(m[f"{s}ELB"], shoulder, pos["T8"], _R_ELBOW)
        hip = pos[f"{side}UpperLeg"]
        knee = (0.5 * (m[f"{s}KNE"] + m[f"{s}KNM"]) if f"{s}KNM" in m
                else _medial(m[f"{s}KNE"], hip, m[f"{other}KNE"], _R_KNEE))
        ankle = (0.5 * (m[f"{s}ANK"] + m[f"{s}MED"]) if f"{s}MED" in m
                 else _medial(m[f"{s}ANK"], knee, m[f"{other}ANK"], _R_ANKLE))
        pos.update({f"{side}UpperArm": shoulder, f"{side}ForeArm": elbow, f"{side}Hand": wrist,
                    f"{side}LowerLeg": knee, f"{side}Foot": ankle, f"{side}Toe": m[f"{s}TOE"]})
        hand_y = wrist - m[f"{s}FIN"] if f"{s}FIN" in m else elbow - wrist
        hand_x = (m[f"{s}WRA"] - m[f"{s}WRB"]) if f"{s}WRB" in m else np.cross(hand_y, left)
        rots[f"{side}Hand"] = _frame(hand_x, hand_y)
    distal = {p: c for c, p in _PARENTS.items() if p is not None and not c.endswith("Toe")}
    distal.pop("Pelvis", None)
    for seg, parent in _PARENTS.items():
        if seg not in rots:  # z along the segment, towards its proximal end (the toes: along the foot)
            axis = pos[seg] - pos[distal[seg]] if seg in distal else pos[seg] - pos[parent]
            rots[seg] = _frame_z(axis, left)
    return pos, rots


def read_c3d(path: str | Path) -> MocapRecording:
    """Read a C3D marker file (Plug-in Gait markers) into a :class:`~wbcbench.teleop.MocapRecording` of the
    canonical segments (module docstring); positions in metres.

    Raises:
        ConfigError: ezc3d missing, an unreadable file, no frames, an unknown unit, or missing markers (one line
            naming the file).
    """
    file = str(path)
    ezc3d = _ezc3d(file)
    try:
        c = ezc3d.c3d(file, extract_forceplat_data=False)
    except Exception as exc:  # ezc3d raises plain RuntimeError / IOError on malformed files
        raise ConfigError(f"not a readable C3D file ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})",
                          file=file) from None
    point = c["parameters"]["POINT"]
    labels = [str(s).strip() for s in point["LABELS"]["value"]]
    for extra in ("LABELS2", "LABELS3"):
        if extra in point:
            labels += [str(s).strip() for s in point[extra]["value"]]
    units = str((point.get("UNITS", {}).get("value") or ["mm"])[0]).strip().lower() or "mm"
    if units not in _UNITS:
        raise ConfigError(f"C3D: unknown POINT:UNITS '{units}'; known: {', '.join(_UNITS)}", file=file)
    rate = float(np.asarray(point["RATE"]["value"]).ravel()[0])
    data = np.asarray(c["data"]["points"], dtype=float)  # (4, P, N)
    if data.ndim != 3 or data.shape[2] == 0:
        raise ConfigError("C3D: no point frames", file=file)
    if not (np.isfinite(rate) and rate > 0):
        raise ConfigError(f"C3D: POINT:RATE must be > 0, got {rate}", file=file)
    xyz = np.transpose(data[:3], (2, 1, 0)) * _UNITS[units]  # (N, P, 3)
    residuals = c["data"].get("meta_points", {}).get("residuals")
    if residuals is not None and np.asarray(residuals).shape == (1, xyz.shape[1], xyz.shape[0]):
        xyz[np.asarray(residuals)[0].T < 0] = np.nan
    return markers_recording(labels, xyz, rate, file)


def markers_recording(labels, xyz: np.ndarray, rate: float, file: str = "") -> MocapRecording:
    """A :class:`~wbcbench.teleop.MocapRecording` of the canonical segments from marker trajectories, for any
    marker file reader: `xyz` (N, P, 3) [m] (NaN: a gap), the P markers' `labels` (a subject prefix ``Name:`` and
    the case do not matter; of equal labels the first is kept; labels past P are ignored), sampled at `rate` [Hz]."""
    markers: dict[str, np.ndarray] = {}
    for k, label in enumerate(labels[: xyz.shape[1]]):
        key = label.rsplit(":", 1)[-1].strip().upper()
        if key and key not in markers:
            markers[key] = xyz[:, k]
    pos, rots = segments_from_markers(markers, file)
    found_set = marker_set(markers)
    names = tuple(_PARENTS)
    positions = np.stack([pos[s] for s in names], axis=1)
    R = np.stack([rots[s] for s in names], axis=1)
    bad = ~np.isfinite(R).all(axis=(2, 3))
    R[bad] = np.eye(3)
    quats = rot.from_matrix(R)
    quats[bad] = np.nan
    positions[~np.isfinite(positions).all(axis=-1)] = np.nan
    n = positions.shape[0]
    return MocapRecording(source=file, frame_rate=rate, times=np.arange(n) / rate, segments=names,
                          positions=positions, orientations=quats,
                          parents=tuple(-1 if p is None else names.index(p) for p in _PARENTS.values()),
                          up_axis="xyz"[int(np.argmax(np.abs(np.nanmean(pos["Neck"] - pos["Pelvis"], axis=0))))],
                          conventions={"marker_set": found_set})


def write_c3d(path: str | Path, markers: dict[str, np.ndarray], rate: float, units: str = "mm") -> Path:
    """Write marker trajectories (label -> (N, 3) [m]; NaN: a gap) to a C3D file in `units` (for tests and
    examples)."""
    ezc3d = _ezc3d(str(path))
    labels = list(markers)
    xyz = np.stack([markers[k] for k in labels], axis=1) / _UNITS[units]  # (N, P, 3)
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rate)]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = [units]
    pts = np.ones((4, len(labels), xyz.shape[0]))
    pts[:3] = np.transpose(xyz, (2, 1, 0))
    c["data"]["points"] = pts
    c.write(str(path))
    return Path(path)
