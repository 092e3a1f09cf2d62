"""Input normalisation shared by the tasks: names, gains, masks, weights, vectors, frame and joint look-ups.

Every function returns a new array that the caller owns (read-only where the task stores it) and raises
:class:`~wbcbench.tasks.exceptions.TaskConfigError` with the task, the key, the value and what is allowed.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.jit import njit
from wbcbench.tasks.exceptions import TaskConfigError, UnknownNameError

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def frozen(array: np.ndarray) -> np.ndarray:
    """Mark ``array`` read-only and return it (so that a task can hand out its internals without copies).
    (``setflags`` costs half of setting ``flags.writeable``, which makes a flags object first: 0.2 against 0.4 us,
    several times a tick.)"""
    array.setflags(write=False)
    return array


def check_name(name: Any, owner: str) -> str:
    """A task name: a non-empty string."""
    if not isinstance(name, str) or not name:
        raise TaskConfigError(owner, "name", f"expected a non-empty string, got {name!r}")
    return name


def as_weight(value: Any, owner: str) -> float:
    """A task weight: a finite float >= 0 (dimensionless, relative to the other tasks of its level)."""
    try:
        weight = float(value)
    except (TypeError, ValueError):
        raise TaskConfigError(owner, "weight", f"expected a finite number >= 0, got {value!r}") from None
    if not math.isfinite(weight) or weight < 0.0:
        raise TaskConfigError(owner, "weight", f"expected a finite number >= 0, got {value!r}")
    return weight


def as_scalar(value: Any, owner: str, key: str, *, minimum: float = 0.0, strict: bool = False) -> float:
    """A finite float >= ``minimum`` (> ``minimum`` if ``strict``)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    ok = math.isfinite(x) and (x > minimum if strict else x >= minimum)
    if not ok:
        bound = f"> {minimum:g}" if strict else f">= {minimum:g}"
        raise TaskConfigError(owner, key, f"expected a finite number {bound}, got {value!r}")
    return x


def as_gain(value: Any, dim: int, owner: str, key: str) -> FloatArray:
    """Per-axis gains: a scalar (broadcast) or a sequence of ``dim`` finite values >= 0. Returns (dim,) read-only."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TaskConfigError(owner, key, f"expected a number or {dim} numbers >= 0, got {value!r}") from None
    if arr.ndim == 0:
        arr = np.full(dim, float(arr))
    elif arr.shape != (dim,):
        raise TaskConfigError(
            owner, key, f"expected a number or {dim} numbers (one per axis), got shape {arr.shape}: {value!r}"
        )
    if not np.all(np.isfinite(arr)):
        raise TaskConfigError(owner, key, f"gains must be finite, got {value!r}")
    if np.any(arr < 0.0):
        raise TaskConfigError(owner, key, f"gains must be >= 0, got {value!r}")
    return frozen(arr)


def as_mask(value: Any, axis_names: Sequence[str], owner: str) -> BoolArray:
    """A row mask: ``len(axis_names)`` booleans (or 0/1), at least one true. Returns (dim,) read-only bool.

    Bit strings such as ``"000111"`` are refused on purpose (they are easy to misread); a YAML loader
    turns them into lists explicitly.
    """
    dim = len(axis_names)
    allowed = f"a sequence of {dim} booleans over ({', '.join(axis_names)})"
    if value is None:
        return frozen(np.ones(dim, dtype=bool))
    if isinstance(value, (str, bytes)):
        raise TaskConfigError(owner, "mask", f"expected {allowed}, got the string {value!r} (pass a list)")
    try:
        items = list(value)
    except TypeError:
        raise TaskConfigError(owner, "mask", f"expected {allowed}, got {value!r}") from None
    if len(items) != dim:
        raise TaskConfigError(owner, "mask", f"expected {allowed}, got {len(items)} entries: {value!r}")
    mask = np.zeros(dim, dtype=bool)
    for i, item in enumerate(items):
        if isinstance(item, (bool, np.bool_)) or (isinstance(item, (int, np.integer)) and item in (0, 1)):
            mask[i] = bool(item)
        else:
            raise TaskConfigError(owner, "mask", f"expected {allowed}, entry {i} is {item!r}")
    if not mask.any():
        raise TaskConfigError(owner, "mask", f"selects no axis of ({', '.join(axis_names)}): {value!r}")
    return frozen(mask)


def as_vector(value: Any, dim: int, owner: str, key: str) -> FloatArray:
    """A finite float vector of shape (dim,) (new array, writeable)."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TaskConfigError(owner, key, f"expected {dim} finite numbers, got {value!r}") from None
    if arr.shape != (dim,):
        raise TaskConfigError(owner, key, f"expected shape ({dim},), got shape {arr.shape}")
    if not np.isfinite(arr).all():  # the method, not np.all: a reference is set every tick
        raise TaskConfigError(owner, key, f"expected finite numbers, got {arr!r}")
    return arr


def close_matches(name: str, candidates: Sequence[str], n: int = 5) -> list[str]:
    """The closest names to ``name`` among ``candidates`` (difflib), best first."""
    matches = difflib.get_close_matches(name, candidates, n=n, cutoff=0.6)
    if not matches:  # a looser pass for short or heavily misspelt names
        matches = difflib.get_close_matches(name, candidates, n=n, cutoff=0.4)
    return matches


def find_frame(model: pin.Model, frame: Any, owner: str, key: str = "frame") -> int:
    """The index of the frame called ``frame``; :class:`UnknownNameError` with suggestions otherwise."""
    if not isinstance(frame, str) or not frame:
        raise TaskConfigError(owner, key, f"expected a frame name (string), got {frame!r}")
    if model.existFrame(frame):
        return int(model.getFrameId(frame))
    names = [f.name for f in model.frames]
    raise UnknownNameError("frame", frame, names, key=key, owner=owner, sort=False)


def find_joint(model: pin.Model, joint: Any, owner: str, key: str = "joints") -> int:
    """The index of the joint called ``joint`` (never the universe); :class:`UnknownNameError` otherwise."""
    if not isinstance(joint, str) or not joint:
        raise TaskConfigError(owner, key, f"expected a joint name (string), got {joint!r}")
    names = list(model.names)[1:]
    if joint in names:
        return names.index(joint) + 1
    raise UnknownNameError("joint", joint, names, key=key, owner=owner, sort=False)


def is_floating_root(model: pin.Model, joint_id: int) -> bool:
    """True for a root joint that is not actuated: a free-flyer or a planar joint attached to the universe."""
    if joint_id < 1 or model.parents[joint_id] != 0:
        return False
    return model.joints[joint_id].shortname() in ("JointModelFreeFlyer", "JointModelPlanar")


def is_rotation(R: FloatArray, tol: float = 1e-5) -> bool:
    """True when R (3, 3) is finite and orthonormal to ``tol`` (``|R'R - I| <= tol`` entrywise); compiled, as it
    is checked on every reference set (under a microsecond; the numpy product R.T @ R costs ten times more)."""
    return bool(_orthonormal(R, float(tol)))


@njit
def _orthonormal(R, tol):
    for i in range(3):
        for j in range(3):
            d = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j] - (1.0 if i == j else 0.0)
            if not abs(d) <= tol:  # NaN compares False
                return False
    return True


def is_vector(x: Any, dim: int) -> bool:
    """True when ``x`` is a float64 numpy array of shape (dim,) (then the compiled copies below take it as is)."""
    return type(x) is np.ndarray and x.dtype == _F64 and x.shape == (dim,)


_F64 = np.dtype(np.float64)
#: an empty vector: "no array" for the optional arguments of the compiled copies
EMPTY = np.zeros(0)


@njit
def copy_finite(a, b, c, a_out, b_out, c_out):
    """Copy three vectors (any of them empty) into the outputs; False (outputs unspecified) unless every value is
    finite. One compiled call for a reference and its derivatives, set every tick."""
    return _copy_finite(a, a_out) and _copy_finite(b, b_out) and _copy_finite(c, c_out)


@njit
def copy_rows_finite(a, b, c, out):
    """`copy_finite` into the rows of ``out`` (3, dim) (the row of an empty input left as it is): a reference and
    its derivatives as the rows of one new array, made read-only once."""
    return _copy_finite(a, out[0]) and _copy_finite(b, out[1]) and _copy_finite(c, out[2])


@njit
def _copy_finite(src, dst):
    for i in range(src.shape[0]):
        x = src[i]
        if not math.isfinite(x):
            return False
        dst[i] = x
    return True


@njit
def copy_pose_checked(p, R, v, a, p_out, R_out, v_out, a_out):
    """`copy_finite` of ``p``, ``v``, ``a``, and ``R`` (3, 3) into ``R_out``, which must be a rotation to 1e-5
    (`is_rotation`)."""
    for i in range(3):
        for j in range(3):
            R_out[i, j] = R[i, j]
    return copy_finite(p, v, a, p_out, v_out, a_out) and _orthonormal(R_out, 1e-5)
