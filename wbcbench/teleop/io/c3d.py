"""C3D marker files (Vicon, Qualisys, OptiTrack exports) through ``ezc3d``: Plug-in Gait or anatomical-landmark
markers -> the segment poses of the retargeting's canonical segments.

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
  y the body's left (the pelvis') made orthogonal; the feet's y from the 1st to the 5th metatarsal head (left
  foot; the reverse for the right) where both are marked, so that a foot's heading is its own.

Other full-body sets with the same head, thorax, arm and leg labels are read through :data:`MARKER_ALIASES`: the
Vicon set of the CMU and HDM05 databases has its pelvis markers on a waist belt (front and back waist, ``LFWT``
``RFWT`` ``LBWT`` ``RBWT``) where Plug-in Gait has the ASIS and PSIS; they stand in for them (the belt sits a few
centimetres above and outside the iliac spines, so the hip joint centres come out that much higher and wider).
The anatomical-landmark set (:data:`ANATOMICAL`: the landmark names of Van Sint Jan's atlas that the ISB
recommendations use, ``L_IAS L_IPS L_FLE L_FME L_FAL L_TAM L_FM1 CV7 SJN SXS L_HLE L_RSP L_HM2`` ..., e.g. the
Rehazenter gait dataset's and Qualisys' full-body sets) is read through :data:`ANATOMICAL_MARKERS` (its landmark
for each Plug-in Gait label, a tuple meaning their midpoint) and :data:`MEDIAL_MARKERS`: with a medial marker the
elbow, knee and ankle centres are the midpoints of the epicondyles / malleoli (ISB) instead of the lateral marker
moved medially. Without head markers (``L_HDF`` ...) the head is the trunk's: its frame the thorax frame (x from
the back markers to the front ones, up from T10/STRN to C7/CLAV), its origin ``HEAD_ABOVE_NECK`` times the
pelvis-to-neck distance above the neck (0.18 to 0.30, median 0.23, measured on the corpus' Plug-in Gait and Vicon
clips); the head then follows the trunk only (said in the detection line, :func:`head_source`).
OpenSim's gait marker set (its Gait2354/Gait2392
examples: ``R.ASIS`` ``V.Sacral`` ``R.Acromium`` ``R.Elbow`` ``R.Wrist.Lat``/``.Med`` ``R.Knee.Lat``/``.Med``
``R.Ankle.Lat``/``.Med`` ``R.Toe.Tip`` ``Sternum``) names the same landmarks otherwise, and has no C7, T10, CLAV
or four head markers:

* thorax from ``Sternum`` and the acromia: Neck at the acromion mid-point, T8 half-way to the sternum marker,
  thorax up from the pelvis centre (ASIS and sacrum mid-points) to the Neck (so it leans with the lumbar spine);
* head from ``R.Temple`` ``L.Temple`` ``Top.Head``: y from the right temple to the left one, z from the temples'
  mid-point towards the head top marker (made orthogonal); the origin 20 cm below the head top along z (the
  temple markers sit forward of the head's centre: the head top, on the vertex, is above it);
* a medial knee or ankle marker (``KNM``/``MED``, the Conventional Gait Model 2's labels) puts the joint centre
  half-way between it and the lateral one instead of the chord offset (:data:`MEDIAL_MARKERS`).

:func:`marker_set` names the set a file's labels follow (from the labels, never the file name).

A marker's gap (no data, or a negative residual) is NaN: the segments built from it are invalid in that frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import ConfigError
from .. import _rotations as rot
from .recording import MocapRecording

__all__ = ["ANATOMICAL", "ANATOMICAL_MARKERS", "C3D_REQUIRED", "MARKER_ALIASES", "MEDIAL_MARKERS", "head_source",
           "marker_set", "markers_recording", "read_c3d", "write_c3d"]

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
#: the anatomical-landmark marker set's name (module docstring)
ANATOMICAL = "anatomical landmark (ISB)"
#: Plug-in Gait label -> the anatomical set's labels for the same landmark (the first present is used; a tuple: the
#: midpoint of its markers): ASIS / PSIS, C7, T10 (or T8), jugular notch (SJN, or SNJ) and xiphoid for CLAV and
#: STRN, the acromioclavicular joint (SAE, or SAJ) for SHO, the lateral epicondyles and malleolus for ELB, KNE and
#: ANK, the radial and ulnar styloids for WRA and WRB, the 2nd/5th metacarpal heads for FIN, the 2nd metatarsal
#: head (or the 1st/5th's midpoint) for TOE, the calcaneus for HEE, the head's front and back markers
ANATOMICAL_MARKERS = {"LASI": ("L_IAS",), "RASI": ("R_IAS",), "LPSI": ("L_IPS",), "RPSI": ("R_IPS",),
                      "C7": ("CV7",), "T10": ("TV10", "TV8"), "CLAV": ("SJN", "SNJ"), "STRN": ("SXS",),
                      "LFHD": ("L_HDF",), "RFHD": ("R_HDF",), "LBHD": ("L_HDB",), "RBHD": ("R_HDB",)}
for _S, _s in (("L", "L_"), ("R", "R_")):
    ANATOMICAL_MARKERS.update({f"{_S}SHO": (f"{_s}SAE", f"{_s}SAJ"), f"{_S}ELB": (f"{_s}HLE",),
                               f"{_S}WRA": (f"{_s}RSP",), f"{_S}WRB": (f"{_s}UHE",),
                               f"{_S}FIN": ((f"{_s}HM2", f"{_s}HM5"), f"{_s}HM2"), f"{_S}KNE": (f"{_s}FLE",),
                               f"{_S}ANK": (f"{_s}FAL",), f"{_S}TOE": (f"{_s}FM2", (f"{_s}FM1", f"{_s}FM5")),
                               f"{_S}HEE": (f"{_s}FCC",)})
del _S, _s
#: lateral label -> the medial marker's labels (the anatomical set's, the Conventional Gait Model 2's, which
#: OpenSim's gait set's medial markers alias): the joint centre is their midpoint
MEDIAL_MARKERS = {f"{S}{j}": (f"{S}_{med}",) + extra for S in "LR" for j, med, extra in (
    ("ELB", "HME", ()), ("KNE", "FME", (f"{S}KNM",)), ("ANK", "TAM", (f"{S}MED",)))}
_HEAD_MARKERS = ("LFHD", "RFHD", "LBHD", "RBHD")
#: the head's origin above the neck, in pelvis-to-neck distances, when the head is the trunk's (module docstring)
HEAD_ABOVE_NECK = 0.23
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
    are there, :data:`ANATOMICAL` when that set's are (``L_IAS``, ``R_IAS``), else the set whose alias labels
    stand in for them (:data:`MARKER_ALIASES`), else "unknown"."""
    labels = set(labels)
    if {"LASI", "RASI"} <= labels:
        return "Plug-in Gait"
    if {"L_IAS", "R_IAS"} <= labels:
        return ANATOMICAL
    for alias, name in _ALIAS_SETS.items():
        if alias in labels:
            return name
    return "unknown"


def _aliases(family: str) -> dict:
    return ANATOMICAL_MARKERS if family == ANATOMICAL else MARKER_ALIASES


def _alias_value(m: dict, alias):
    """The alias's positions: a label's, or the midpoint of a tuple's labels (None if one is missing)."""
    if isinstance(alias, tuple):
        return np.mean([m[a] for a in alias], axis=0) if all(a in m for a in alias) else None
    return m.get(alias)


def with_aliases(m: dict[str, np.ndarray], family: str | None = None) -> dict[str, np.ndarray]:
    """`m` with each missing Plug-in Gait label filled from its first present alias in the marker set `family`
    (default: the one `m`'s labels follow; :data:`MARKER_ALIASES`, :data:`ANATOMICAL_MARKERS`)."""
    out = dict(m)
    for label, aliases in _aliases(marker_set(m) if family is None else family).items():
        if label not in out:
            found = next((v for v in (_alias_value(m, a) for a in aliases) if v is not None), None)
            if found is not None:
                out[label] = found
    return out


def head_source(labels) -> str:
    """Where the head's pose comes from for upper-case marker `labels`: "markers" (four head markers), or "trunk"
    (an anatomical set without them: the thorax frame, module docstring)."""
    m = with_aliases(dict.fromkeys(labels, 0.0))
    if all(k in m for k in _HEAD_MARKERS) or marker_set(labels) != ANATOMICAL:
        return "markers"
    return "trunk"


def _needed(label: str, family: str) -> str:
    """How `label` is spelled in the marker set `family` (the anatomical set's alternatives joined by '|', a
    midpoint's by '+'; other sets: the label and its :data:`MARKER_ALIASES` joined by '/')."""
    if family != ANATOMICAL:
        return label + "".join(f"/{a}" for a in MARKER_ALIASES.get(label, ()))
    return "|".join("+".join(a) if isinstance(a, tuple) else a for a in ANATOMICAL_MARKERS.get(label, (label,)))


def segments_from_markers(m: dict[str, np.ndarray], file: str = "") -> tuple[dict, dict]:
    """(segment -> (N, 3) origin, segment -> (N, 3, 3) orientation) from Plug-in Gait markers (module docstring);
    `m`: marker label (upper case) -> (N, 3) positions [m]; labels of other marker sets are read through
    :data:`MARKER_ALIASES`."""
    family = marker_set(m)
    head = head_source(m)
    labels = sorted(m)
    m = with_aliases(m, family)
    sets = {}
    missing = [_needed(k, family) for k in C3D_REQUIRED
               if k not in m and k not in _THORAX_SETS[0] + _HEAD_SETS[0]]  # the thorax and head: below
    if not ("SACR" in m or ("LPSI" in m and "RPSI" in m)):
        missing.append("L_IPS+R_IPS" if family == ANATOMICAL else "LPSI+RPSI or SACR")
    for part, options in (("thorax", _THORAX_SETS), ("head", _HEAD_SETS)):
        if family == ANATOMICAL:  # its own landmarks for Plug-in Gait's, or (head) the trunk's
            options = options[:1]
        sets[part] = next((k for k, o in enumerate(options) if all(label in m for label in o)), None)
        if sets[part] is None and not (part == "head" and head == "trunk"):
            if family == ANATOMICAL:
                missing += [_needed(k, family) for k in options[0] if k not in m]
            else:
                missing.append(" or ".join("+".join(o) for o in options))
    if missing:
        kind = f"{family} markers" if family != "unknown" else "markers"
        raise ConfigError(f"{kind} {missing} not found (labels: {', '.join(labels[:12])}"
                          f"{', ...' if len(labels) > 12 else ''}); a full-body set is needed: Plug-in Gait, the "
                          "CMU/HDM05 Vicon waist set, OpenSim's gait set or the anatomical-landmark (ISB) set",
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
    if head == "trunk":  # the thorax frame, the origin above the neck (module docstring)
        head_x = _unit(_perp(0.5 * (m["CLAV"] + m["STRN"]) - 0.5 * (m["C7"] + m["T10"]), up))
        head_up = up
        trunk = float(np.nanmedian(np.linalg.norm(top - asis, axis=-1)))
        pos["Head"] = top + HEAD_ABOVE_NECK * trunk * up
    elif sets["head"] == 0:
        front, rear = 0.5 * (m["LFHD"] + m["RFHD"]), 0.5 * (m["LBHD"] + m["RBHD"])
        R_head = _frame(front - rear, 0.5 * (m["LFHD"] + m["LBHD"]) - 0.5 * (m["RFHD"] + m["RBHD"]))
        head_x, head_left = R_head[..., 0], R_head[..., 1]
        head_up = np.cross(head_x, head_left)
        pos["Head"] = 0.25 * (m["LFHD"] + m["RFHD"] + m["LBHD"] + m["RBHD"]) - _HEAD_DROP * head_up
    else:  # two temples and the head top (OpenSim's gait set)
        temples = 0.5 * (m["L.TEMPLE"] + m["R.TEMPLE"])
        R_head = _frame_z(m["TOP.HEAD"] - temples, m["L.TEMPLE"] - m["R.TEMPLE"])
        head_x, head_up = R_head[..., 0], R_head[..., 2]
        pos["Head"] = m["TOP.HEAD"] - 2 * _HEAD_DROP * head_up  # 20 cm below the vertex (module docstring)
    rots: dict[str, np.ndarray] = {"Pelvis": R_pelvis,
                                   "Head": np.stack([head_x, head_up, np.cross(head_x, head_up)], axis=-1)}
    left = y
    for side, s in (("Left", "L"), ("Right", "R")):
        other = "R" if s == "L" else "L"
        shoulder = m[f"{s}SHO"] - _SHOULDER_DROP * up
        wrist = 0.5 * (m[f"{s}WRA"] + m[f"{s}WRB"]) if f"{s}WRB" in m else m[f"{s}WRA"]
        medial = {k: next((m[a] for a in MEDIAL_MARKERS[k] if a in m), None) for k in
                  (f"{s}ELB", f"{s}KNE", f"{s}ANK")}
        hip = pos[f"{side}UpperLeg"]

        def centre(label, proximal, towards, radius):
            if medial[label] is not None:  # the epicondyles' / malleoli's midpoint
                return 0.5 * (m[label] + medial[label])
            return _medial(m[label], proximal, towards, radius)

        elbow = centre(f"{s}ELB", shoulder, pos["T8"], _R_ELBOW)
        knee = centre(f"{s}KNE", hip, m[f"{other}KNE"], _R_KNEE)
        ankle = centre(f"{s}ANK", knee, m[f"{other}ANK"], _R_ANKLE)
        pos.update({f"{side}UpperArm": shoulder, f"{side}ForeArm": elbow, f"{side}Hand": wrist,
                    f"{side}LowerLeg": knee, f"{side}Foot": ankle, f"{side}Toe": m[f"{s}TOE"]})
        hand_y = wrist - m[f"{s}FIN"] if f"{s}FIN" in m else elbow - wrist
        hand_x = (m[f"{s}WRA"] - m[f"{s}WRB"]) if f"{s}WRB" in m else np.cross(hand_y, left)
        rots[f"{side}Hand"] = _frame(hand_x, hand_y)
    distal: dict[str, str] = {}  # a segment's first child: T8's is the Neck (along the spine), not an arm
    for c, p in _PARENTS.items():
        if p is not None and not c.endswith("Toe"):
            distal.setdefault(p, c)
    distal.pop("Pelvis", None)
    hints = {}  # the feet's left: across the forefoot where the 1st and 5th metatarsal heads are marked
    for side, s, sign in (("Left", "L", 1.0), ("Right", "R", -1.0)):
        if f"{s}_FM1" in m and f"{s}_FM5" in m:
            hints[f"{side}Foot"] = hints[f"{side}Toe"] = sign * (m[f"{s}_FM5"] - m[f"{s}_FM1"])
    for seg, parent in _PARENTS.items():
        if seg not in rots:  # z along the segment, towards its proximal end (the toes: along the foot)
            axis = pos[seg] - pos[distal[seg]] if seg in distal else pos[seg] - pos[parent]
            rots[seg] = _frame_z(axis, hints.get(seg, left))
    return pos, rots


def read_c3d(path: str | Path) -> MocapRecording:
    """Read a C3D marker file (Plug-in Gait or anatomical-landmark markers) into a
    :class:`~wbcbench.teleop.MocapRecording` of the canonical segments (module docstring); positions in metres.

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
    notes = ["head from the trunk (no head markers)"] if head_source(markers) == "trunk" else []
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
                          conventions={"marker_set": found_set, "notes": notes})


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
