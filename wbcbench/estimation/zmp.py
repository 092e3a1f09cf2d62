"""Centre of pressure of one foot and the ZMP of several contact wrenches on a plane.

For a wrench (F, M_o) with its moment about a point o of a plane with unit normal n, the point p of the
plane about which the moment has no tangential component (the CoP / ZMP) is

    p = o + (n x M_o) / (n . F)

On the horizontal ground z = h (n = e_z, o = (0, 0, h)) this is the textbook
p_x = -M_y / F_z, p_y = M_x / F_z, p_z = h. The ZMP of several feet is the CoP of their summed wrench
(Kajita et al., "Introduction to Humanoid Robotics", ch. 3 "ZMP and Dynamics"), which is also the
normal-force-weighted mean of the per-foot CoPs when all lie on the same plane. Paper 000 reports an
"estimated ZMP" without its formula (REFERENCE.md: from the two ankle F/T sensors); this is the standard one.

A foot whose normal force n . F is below `min_normal_force` (default 10 N, SIM-NOTES.md) is treated as
unloaded: it has no CoP (NaN) and is left out of the ZMP, so that the residual wrench a swinging foot reads
on its F/T sensor does not pollute the estimate.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ._validate import batch_size, cross, positive_scalar, vec3
from .wrench import Wrench, _validated_wrench

DEFAULT_MIN_NORMAL_FORCE = 10.0
"""Normal force [N] below which a foot is treated as unloaded."""


class Plane(NamedTuple):
    """A plane in world: a point on it and its unit normal (pointing out of the ground).

    Attributes:
        point: (3,) or (N, 3) a point of the plane [m], world frame.
        normal: (3,) or (N, 3) unit normal, world frame (normalised by `as_plane`).
    """

    point: np.ndarray
    normal: np.ndarray

    @classmethod
    def horizontal(cls, height: float = 0.0) -> Plane:
        """The horizontal plane z = `height` [m], normal +z."""
        return cls(np.array([0.0, 0.0, float(height)]), np.array([0.0, 0.0, 1.0]))


def as_plane(ground: float | Plane) -> Plane:
    """Validate `ground`: a height [m] (horizontal plane) or a Plane; returns a Plane with unit normals."""
    if isinstance(ground, Plane):
        point = vec3("ground.point", ground.point)
        normal = vec3("ground.normal", ground.normal)
        batch_size(**{"ground.point": (point, 1), "ground.normal": (normal, 1)})
        norm = np.linalg.norm(normal, axis=-1, keepdims=True)
        if np.any(norm < 1e-9):
            raise ValueError("ground.normal must be non-zero")
        return Plane(point, normal / norm)
    if isinstance(ground, (bool, np.bool_)) or not isinstance(ground, (int, float, np.integer, np.floating)):
        raise ValueError(f"ground must be a height [m] or a Plane, got {type(ground).__name__}")
    if not np.isfinite(ground):
        raise ValueError(f"ground height must be finite, got {ground!r}")
    return Plane.horizontal(float(ground))


class CenterOfPressure(NamedTuple):
    """Per-foot centre of pressure.

    Attributes:
        point: (3,) or (N, 3) CoP on the plane [m], world frame; NaN where the foot is unloaded.
        normal_force: () or (N,) normal force n . F [N].
        loaded: () or (N,) bool, normal_force >= min_normal_force.
    """

    point: np.ndarray
    normal_force: np.ndarray
    loaded: np.ndarray


def _on_plane(f: np.ndarray, m: np.ndarray, p: np.ndarray, plane: Plane) -> tuple[np.ndarray, np.ndarray]:
    """Normal force n . F and moment about the plane point for one wrench (broadcast arrays)."""
    moment_o = m + cross(p - plane.point, f)
    if plane.normal.ndim == 1 and f.ndim == 1:
        return np.float64(plane.normal @ f), moment_o
    fn = np.einsum("...i,...i->...", plane.normal, f)
    return fn, moment_o


def _point_from_moment(fn: np.ndarray, moment_o: np.ndarray, plane: Plane, ok: np.ndarray) -> np.ndarray:
    safe_fn = np.where(ok, fn, 1.0)
    r = cross(plane.normal, moment_o) / safe_fn[..., None]
    point = plane.point + r
    return np.where(ok[..., None], point, np.nan)


def center_of_pressure(
    wrench: Wrench,
    ground: float | Plane = 0.0,
    *,
    min_normal_force: float = DEFAULT_MIN_NORMAL_FORCE,
) -> CenterOfPressure:
    """Centre of pressure of one contact wrench on a plane (the sole plane for a foot).

    Args:
        wrench: the ground's wrench on the foot, world frame (from `contact_wrench_from_ft`).
        ground: a height [m] (horizontal plane) or a `Plane` (e.g. the sole plane on a tilted platform).
        min_normal_force: threshold [N], >= 0; below it the foot is unloaded and its CoP is NaN.

    Returns:
        CenterOfPressure(point, normal_force, loaded).
    """
    f, m, p = _validated_wrench(wrench, "wrench")
    plane = as_plane(ground)
    threshold = positive_scalar("min_normal_force", min_normal_force, allow_zero=True)
    batch_size(wrench=(f, 1), **{"ground.point": (plane.point, 1), "ground.normal": (plane.normal, 1)})
    fn, moment_o = _on_plane(f, m, p, plane)
    loaded = (fn >= threshold) & (fn > 0.0)
    point = _point_from_moment(fn, moment_o, plane, loaded)
    if f.shape == plane.point.shape == plane.normal.shape == (3,):  # one sample: nothing to broadcast
        return CenterOfPressure(np.array(point, dtype=float), np.float64(fn), np.bool_(loaded))
    shape = np.broadcast_shapes(f.shape, plane.point.shape, plane.normal.shape)
    point = np.broadcast_to(point, shape).copy()
    fn = np.broadcast_to(fn, shape[:-1]).copy()
    loaded = np.broadcast_to(loaded, shape[:-1]).copy()
    return CenterOfPressure(point, fn, loaded)


def zmp_from_wrenches(
    wrenches: Sequence[Wrench],
    ground: float | Plane = 0.0,
    *,
    min_normal_force: float = DEFAULT_MIN_NORMAL_FORCE,
) -> np.ndarray:
    """ZMP of the summed contact wrenches (e.g. both feet) on a plane.

    Each wrench enters a tick only if its own normal force is >= `min_normal_force`; the ZMP is the CoP
    of the sum of the entering wrenches: p = o + n x (sum M_o) / (n . sum F).

    Args:
        wrenches: one Wrench per foot (world frame, any reduction points), each (3,) or (N, 3).
        ground: a height [m] (horizontal plane z = height) or a `Plane`.
        min_normal_force: per-foot threshold [N], >= 0.

    Returns:
        (3,) or (N, 3) ZMP on the plane [m], world frame; NaN rows where no foot is loaded.
    """
    if isinstance(wrenches, Wrench) or not isinstance(wrenches, Sequence) or len(wrenches) == 0:
        raise ValueError("wrenches must be a non-empty sequence of Wrench (one per foot)")
    plane = as_plane(ground)
    threshold = positive_scalar("min_normal_force", min_normal_force, allow_zero=True)
    parts = [_validated_wrench(w, f"wrenches[{k}]") for k, w in enumerate(wrenches)]
    batch_size(
        **{f"wrenches[{k}]": (f, 1) for k, (f, _, _) in enumerate(parts)},
        **{"ground.point": (plane.point, 1), "ground.normal": (plane.normal, 1)},
    )
    shape = np.broadcast_shapes(plane.point.shape, plane.normal.shape, *(f.shape for f, _, _ in parts))
    fn_total = np.zeros(shape[:-1])
    moment_total = np.zeros(shape)
    any_loaded = np.zeros(shape[:-1], dtype=bool)
    for f, m, p in parts:
        fn, moment_o = _on_plane(f, m, p, plane)
        loaded = fn >= threshold
        fn_total = fn_total + np.where(loaded, fn, 0.0)
        moment_total = moment_total + np.where(loaded[..., None], moment_o, 0.0)
        any_loaded |= loaded
    ok = any_loaded & (fn_total > 0.0)
    return np.broadcast_to(_point_from_moment(fn_total, moment_total, plane, ok), shape).copy()
