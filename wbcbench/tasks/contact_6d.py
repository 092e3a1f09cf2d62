"""Rigid 6D surface contact: motion constraint rows and wrench inequalities for a rectangular sole."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.tasks import _validation as val
from wbcbench.tasks.exceptions import ReferenceNotSetError, TaskConfigError
from wbcbench.tasks.rows import Inequality
from wbcbench.tasks.task import Task

__all__ = ["DRIFTS", "Contact6D", "as_wrench_metric", "sole_corners", "tsid_wrench_metric"]

FloatArray = npt.NDArray[np.float64]

_LOCAL = pin.ReferenceFrame.LOCAL

#: Names of the wrench inequality rows of :meth:`Contact6D.force_rows`, in order.
FORCE_ROW_NAMES: tuple[str, ...] = (
    "friction +fx",
    "friction -fx",
    "friction +fy",
    "friction -fy",
    "cop y max",  # tau_x <= (c_y + W/2) f_z at the origin: CoP y <= c_y + W/2
    "cop y min",
    "cop x min",  # tau_y <= -(c_x - L/2) f_z: CoP x >= c_x - L/2
    "cop x max",
    "yaw min ++",
    "yaw min +-",
    "yaw min -+",
    "yaw min --",
    "yaw max ++",
    "yaw max +-",
    "yaw max -+",
    "yaw max --",
    "min normal force",
    "max normal force",
)


#: The drift conventions of a contact's motion rows (`Contact6D`'s ``drift``).
DRIFTS: tuple[str, ...] = ("spatial", "classical")
#: The pose-error conventions of a contact's motion rows (`Contact6D`'s ``error``).
ERRORS: tuple[str, ...] = ("log6", "split")

#: TSID's Contact6d weights of the wrench axes (fx fy fz tx ty tz) in its force regularisation.
TSID_WRENCH_AXIS_WEIGHTS: tuple[float, ...] = (1.0, 1.0, 1e-3, 2.0, 2.0, 2.0)


def _skew(p: npt.ArrayLike) -> FloatArray:
    x, y, z = np.asarray(p, dtype=np.float64)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


class Contact6D(Task):
    """A rigid planar contact between the rectangular sole of frame ``frame`` and the environment.

    Frame convention: the contact frame is ``frame`` itself (e.g. ``"left_sole_link"``); its local z axis is
    the contact normal, pointing out of the environment into the robot, and the sole is a ``length`` x
    ``width`` rectangle in its local x-y plane (length along local x), centred at ``center`` = (c_x, c_y)
    [m] in that plane (the frame origin must lie on the sole surface).

    **Motion rows** (the :class:`~wbcbench.tasks.task.Task` contract, 6 axes ``x y z roll pitch yaw`` in the
    LOCAL frame). Twist ``nu = J v`` with ``J = pin.getFrameJacobian(..., LOCAL)``; error
    ``e = log6(T_world_frame^-1 T_world_ref)`` (the local twist that takes the frame to its reference pose;
    ``d e/dt = -J v`` for small errors), or with ``error="split"`` the translation and the rotation apart,
    ``e = [R^T (p_ref - p); log3(R^T R_ref)]`` (C++ TSID's contacts; the two agree to first order, they differ
    off the reference by terms in rotation error x translation error); drift ``J_dot v`` by the convention
    ``drift``:

    * ``"spatial"`` (default): the spatial acceleration in LOCAL at zero joint acceleration
      (``pin.getFrameAcceleration(..., LOCAL)``), the exact time derivative of the local twist ``J v``;
    * ``"classical"``: the classical acceleration, the spatial one's linear part plus ``omega x v``
      (``pin.getFrameClassicalAcceleration(..., LOCAL)``), the second derivative of the frame origin's position
      in the frame's axes, as C++ TSID's contacts (and frame tasks) take it. The two differ by ``omega x v``,
      zero for a sole at rest: they give the same rows when the contact holds, not when the sole slides or turns.

    The shared formulation then gives ``J dv = -J_dot v + Kp e + Kd (-J v)`` (references velocity and
    acceleration stay zero). TSID position/torque use Kp 30, Kd 11 (paper 000 Table 1). The reference is set when
    the contact is created or made (``set_reference`` / ``set_reference_to_current``).

    **Wrench** ``w = [f; tau]`` (N, N m): the wrench exerted by the environment on the robot, expressed in the
    contact frame at its origin. It enters the dynamics as ``M dv + nle = S^T tau_joints + J^T w`` with the
    same LOCAL Jacobian ``J`` as the motion rows.

    **Force rows** ``C w <= u`` (:meth:`force_rows`, 18 rows named in :data:`FORCE_ROW_NAMES`): the contact
    wrench cone of a rectangle (Caron, Pham, Nakamura, ICRA 2015, "Stability of surface contacts for humanoid
    robots: closed-form formulae of the contact wrench cone for rectangular support areas"), computed at the
    rectangle centre and mapped to the frame origin:

    * friction pyramid ``|f_x| <= mu_lin f_z``, ``|f_y| <= mu_lin f_z`` with ``mu_lin = mu / sqrt(2)``, the
      4-sided pyramid inscribed in the Coulomb cone (conservative; the same linearisation as TSID's contacts);
    * centre of pressure inside the rectangle: ``|tau_y| <= (L/2) f_z``, ``|tau_x| <= (W/2) f_z`` at the centre;
    * yaw torque bounded by the friction available at the corners (8 rows);
    * ``f_min <= f_z <= f_max``.

    This is exactly the set of wrenches generated by four corner forces each inside its inscribed pyramid
    (:meth:`corner_wrench_map`), so a 4-point parametrisation and this 6D one agree.

    **Wrench metric** (``wrench_metric``, optional): a symmetric positive semi-definite (6, 6) ``W`` whose
    ``w^T W w`` is this contact's wrench regularisation in an inverse-dynamics QP (the Hessian block of its
    wrench, in the QP's ``1/2 x^T H x`` scale), replacing the formulation's diagonal one; None (default): the
    formulation's. :func:`tsid_wrench_metric` gives C++ TSID's.

    Args:
        model: robot model (read at construction to resolve the frame).
        frame: contact frame name.
        length: sole length along local x [m], > 0.
        width: sole width along local y [m], > 0.
        center: rectangle centre (c_x, c_y) in the frame's x-y plane [m].
        mu: Coulomb friction coefficient, > 0 (default 0.3, as in TSID's TALOS walking demo; the paper gives
            none).
        min_normal_force: ``f_min`` [N], >= 0 (default 0).
        max_normal_force: ``f_max`` [N], >= ``f_min`` (default 2000 N, about 2.3 times TALOS' weight: not
            binding while walking, but finite for the QP; see :meth:`set_max_force` to ramp a contact out).
        kp, kd: motion-row gains per axis (LOCAL x y z roll pitch yaw); ``kd=None`` gives ``2 sqrt(kp)``.
        weight: weight if a formulation treats contact motion as a soft task (hard constraints ignore it).
        name: contact name; defaults to the frame name.
        drift: the motion rows' drift convention, ``"spatial"`` (default) or ``"classical"`` (see above).
        error: the motion rows' pose error, ``"log6"`` (default) or ``"split"`` (see above).
        wrench_metric: (6, 6) symmetric PSD metric of the wrench regularisation, None: the formulation's.

    Raises:
        UnknownNameError: ``frame`` is not in the model.
        TaskConfigError: invalid geometry, friction, force bounds, gains, weight, drift, error or wrench
            metric.
    """

    AXES = ("x", "y", "z", "roll", "pitch", "yaw")
    UNITS = ("m", "m", "m", "rad", "rad", "rad")
    FORCE_ROW_NAMES = FORCE_ROW_NAMES

    def __init__(
        self,
        model: pin.Model,
        frame: str,
        *,
        length: float,
        width: float,
        kp: Any,
        kd: Any = None,
        center: Sequence[float] = (0.0, 0.0),
        mu: float = 0.3,
        min_normal_force: float = 0.0,
        max_normal_force: float = 2000.0,
        weight: float = 1.0,
        name: str | None = None,
        drift: str = "spatial",
        wrench_metric: npt.ArrayLike | None = None,
        error: str = "log6",
    ) -> None:
        owner_name = frame if name is None else name
        owner = f"{type(self).__name__} {owner_name!r}"
        self._frame_id = val.find_frame(model, frame, owner)
        self._frame = frame
        super().__init__(
            name=owner_name, axis_names=self.AXES, units=self.UNITS, weight=weight, kp=kp, kd=kd, mask=None
        )
        self._length = val.as_scalar(length, owner, "length", strict=True)
        self._width = val.as_scalar(width, owner, "width", strict=True)
        self._center = val.frozen(val.as_vector(center, 2, owner, "center"))
        self._mu = val.as_scalar(mu, owner, "mu", strict=True)
        self._f_min = val.as_scalar(min_normal_force, owner, "min_normal_force")
        f_max = val.as_scalar(max_normal_force, owner, "max_normal_force")
        if f_max < self._f_min:
            raise TaskConfigError(
                owner, "max_normal_force", f"must be >= min_normal_force ({self._f_min:g} N), got {f_max:g}"
            )
        self._f_max_nominal = f_max
        if drift not in DRIFTS:
            raise TaskConfigError(owner, "drift", f"must be one of {', '.join(DRIFTS)}, got {drift!r}")
        self._drift = drift
        if error not in ERRORS:
            raise TaskConfigError(owner, "error", f"must be one of {', '.join(ERRORS)}, got {error!r}")
        self._error_convention = error
        self._wrench_metric = None
        if wrench_metric is not None:
            try:
                self._wrench_metric = val.frozen(as_wrench_metric(wrench_metric))
            except ValueError as exc:
                raise TaskConfigError(owner, "wrench_metric", str(exc)) from None
        self._C_surface = self._C = val.frozen(self._wrench_cone_matrix(self._length, self._center))
        self._edge: str | None = None
        self._edge_cones: dict = {}
        # the reference placement: its rotation and translation (new arrays at each `set_reference`), and the SE3
        # made from them when asked for (`_M_ref`)
        self._R_ref: FloatArray | None = None
        self._p_ref: FloatArray | None = None
        self._M_cache: pin.SE3 | None = None
        self.set_max_force(f_max)

    # ---------------------------------------------------------------------------------------- geometry
    @property
    def drift_convention(self) -> str:
        """The motion rows' drift convention: ``"spatial"`` or ``"classical"`` (class docstring)."""
        return self._drift

    @property
    def error_convention(self) -> str:
        """The motion rows' pose error: ``"log6"`` or ``"split"`` (class docstring)."""
        return self._error_convention

    @property
    def wrench_metric(self) -> FloatArray | None:
        """The (6, 6) metric of this contact's wrench regularisation (read-only), None: the formulation's."""
        return self._wrench_metric

    @property
    def frame(self) -> str:
        """Name of the contact frame."""
        return self._frame

    @property
    def frame_id(self) -> int:
        """Index of the contact frame in the model."""
        return self._frame_id

    @property
    def length(self) -> float:
        """Sole length along local x [m]."""
        return self._length

    @property
    def width(self) -> float:
        """Sole width along local y [m]."""
        return self._width

    @property
    def center(self) -> FloatArray:
        """Rectangle centre (c_x, c_y) in the frame's x-y plane [m], read-only."""
        return self._center

    @property
    def mu(self) -> float:
        """Coulomb friction coefficient."""
        return self._mu

    @property
    def mu_pyramid(self) -> float:
        """Friction coefficient of the inscribed 4-sided pyramid, ``mu / sqrt(2)``."""
        return self._mu / math.sqrt(2.0)

    @property
    def corners(self) -> FloatArray:
        """The 4 sole corners in the contact frame, (4, 3) [m]: (+x +y), (+x -y), (-x +y), (-x -y)."""
        return sole_corners(self._length, self._width, self._center)

    def corner_wrench_map(self) -> FloatArray:
        """``G`` (6, 12) with ``w = G [f_1; f_2; f_3; f_4]``, corner forces (N) in the contact frame, in the
        order of :attr:`corners`; wrench at the frame origin."""
        G = np.zeros((6, 12))
        for i, p in enumerate(self.corners):
            G[:3, 3 * i : 3 * i + 3] = np.eye(3)
            G[3:, 3 * i : 3 * i + 3] = _skew(p)
        return G

    #: the depth [m] along the sole of the strip an edge contact presses through (`set_edge`)
    EDGE_DEPTH = 0.005

    @property
    def edge(self) -> str | None:
        """The sole edge the contact is on (``"toe"`` or ``"heel"``), None for the whole sole (`set_edge`)."""
        return self._edge

    def edge_x(self, edge: str) -> float:
        """The x [m] in the contact frame of the sole's front (``"toe"``) or back (``"heel"``) edge."""
        if edge not in ("toe", "heel"):
            raise TaskConfigError(self.owner, "edge", f"must be 'toe', 'heel' or None, got {edge!r}")
        return float(self._center[0] + (0.5 if edge == "toe" else -0.5) * self._length)

    def set_edge(self, edge: str | None) -> None:
        """Put the contact on a line of the sole, its front (``"toe"``) or back (``"heel"``) edge, or back on the
        whole sole (None). On an edge the wrench rows are those of a strip `EDGE_DEPTH` deep along that edge
        (the centre of pressure on the edge, the friction and yaw rows of the strip): the foot may turn about the
        edge (its pitch given by the contact's reference, `set_reference` with a velocity and acceleration)."""
        if edge == self._edge:
            return
        if edge is None:
            self._C = self._C_surface
        else:
            C = self._edge_cones.get(edge)
            if C is None:
                x = self.edge_x(edge)
                depth = min(self.EDGE_DEPTH, self._length)
                cx = x - 0.5 * depth if edge == "toe" else x + 0.5 * depth
                C = self._edge_cones[edge] = val.frozen(
                    self._wrench_cone_matrix(depth, np.array([cx, self._center[1]])))
            self._C = C
        self._edge = edge

    def _wrench_cone_matrix(self, length: float, center: FloatArray) -> FloatArray:
        """C (18, 6) acting on the wrench at the frame origin (see the class docstring), for a rectangle of the
        given length and the sole's width centred at `center`."""
        mu = self.mu_pyramid
        X, Y = 0.5 * length, 0.5 * self._width
        # Rows on the wrench at the rectangle centre, [fx fy fz tx ty tz].
        rows = [
            [1, 0, -mu, 0, 0, 0],
            [-1, 0, -mu, 0, 0, 0],
            [0, 1, -mu, 0, 0, 0],
            [0, -1, -mu, 0, 0, 0],
            [0, 0, -Y, 1, 0, 0],
            [0, 0, -Y, -1, 0, 0],
            [0, 0, -X, 0, 1, 0],
            [0, 0, -X, 0, -1, 0],
        ]
        signs = ((1, 1), (1, -1), (-1, 1), (-1, -1))
        # tau_min <= tau_z: s1 (Y fx - mu tx) + s2 (X fy - mu ty) - mu (X + Y) fz - tz <= 0
        for s1, s2 in signs:
            rows.append([s1 * Y, s2 * X, -mu * (X + Y), -s1 * mu, -s2 * mu, -1])
        # tau_z <= tau_max: s1 (Y fx + mu tx) + s2 (X fy + mu ty) - mu (X + Y) fz + tz <= 0
        for s1, s2 in signs:
            rows.append([s1 * Y, s2 * X, -mu * (X + Y), s1 * mu, s2 * mu, 1])
        rows.append([0, 0, -1, 0, 0, 0])
        rows.append([0, 0, 1, 0, 0, 0])
        C_center = np.array(rows, dtype=np.float64)
        # Wrench at the centre c from the wrench at the origin: [f; tau - c x f].
        T = np.eye(6)
        T[3:, :3] = -_skew([center[0], center[1], 0.0])
        return C_center @ T

    # ------------------------------------------------------------------------------------ force bounds
    @property
    def max_normal_force(self) -> float:
        """Current upper bound on ``f_z`` [N] (see :meth:`set_max_force`)."""
        return self._f_max

    @property
    def nominal_max_normal_force(self) -> float:
        """The ``max_normal_force`` given at construction [N]."""
        return self._f_max_nominal

    @property
    def min_normal_force(self) -> float:
        """Current lower bound on ``f_z`` [N]: ``min(min_normal_force, max_normal_force)``."""
        return min(self._f_min, self._f_max)

    def set_max_force(self, f_max: float) -> None:
        """Set the current upper bound on the normal force [N], >= 0.

        Ramp it to zero before breaking a contact; the lower bound follows it down when it goes below
        ``min_normal_force`` (so the rows stay feasible: at 0 the only admissible wrench is zero).
        Restore with ``set_max_force(contact.nominal_max_normal_force)``.
        """
        f = val.as_scalar(f_max, self.owner, "max_normal_force")
        self._f_max = f
        u = np.zeros(len(FORCE_ROW_NAMES))
        u[-2] = -min(self._f_min, f)
        u[-1] = f
        self._u = val.frozen(u)

    def force_rows(self) -> Inequality:
        """``C w <= u`` on the contact wrench (contact frame, at its origin): C (18, 6), u (18,), read-only."""
        return Inequality(self._C, self._u)

    def inside(self, wrench: npt.ArrayLike, tol: float = 1e-9) -> bool:
        """True when ``wrench`` (6,) [N, N m] satisfies every force row within ``tol``."""
        w = val.as_vector(wrench, 6, self.owner, "wrench")
        return bool(np.all(self._C @ w <= self._u + tol))

    def cop(self, wrench: npt.ArrayLike) -> FloatArray:
        """Centre of pressure (x, y) in the contact frame [m] of ``wrench`` (6,), ``f_z`` must be > 0."""
        w = val.as_vector(wrench, 6, self.owner, "wrench")
        if w[2] <= 0.0:
            raise TaskConfigError(self.owner, "wrench", f"the CoP needs f_z > 0, got {w[2]:g} N")
        return np.array([-w[4] / w[2], w[3] / w[2]])

    # ---------------------------------------------------------------------------------------- references
    def set_reference(self, pose: Any, velocity: npt.ArrayLike | None = None,
                      acceleration: npt.ArrayLike | None = None) -> None:
        """Set the contact's reference placement ``T_world_ref`` (where the sole should stay): a `pinocchio.SE3`,
        or a pose with ``position`` (3,) and ``rotation`` (3, 3) (e.g. `wbcbench.types.PoseReference`: a
        stabilizer's per-tick pose without making an SE3). velocity, acceleration: the reference's twist (6,) in
        the LOCAL frame and its derivative (a sole turning about an edge, `set_edge`); None: at rest."""
        derivatives = self._check_derivatives(velocity, acceleration)
        if isinstance(pose, pin.SE3):
            position, rotation = pose.translation, pose.rotation
        else:
            position, rotation = getattr(pose, "position", None), getattr(pose, "rotation", None)
            if position is None or rotation is None:
                raise TaskConfigError(self.owner, "pose", "expected a pinocchio.SE3 or a pose with a position and "
                                      f"a rotation (e.g. a PoseReference), got {type(pose).__name__}")
            position = np.asarray(position, dtype=np.float64)
            rotation = np.asarray(rotation, dtype=np.float64)
            if position.shape != (3,) or rotation.shape != (3, 3):
                raise TaskConfigError(self.owner, "pose", f"expected a (3,) position and a (3, 3) rotation, got "
                                      f"{position.shape} and {rotation.shape}")
        R, p = np.empty((3, 3)), np.empty(3)
        E = val.EMPTY
        if not val.copy_pose_checked(position, rotation, E, E, p, R, E, E):
            raise TaskConfigError(self.owner, "pose", "expected a finite rigid transform")
        self._R_ref, self._p_ref, self._M_cache = R, p, None  # private (handed out as an SE3 copy)
        self._store_derivatives(derivatives)

    @property
    def _M_ref(self) -> pin.SE3 | None:
        """The reference placement as an SE3 (made once per `set_reference`), None before the first."""
        if self._M_cache is None and self._R_ref is not None:
            self._M_cache = pin.SE3(self._R_ref, self._p_ref)
        return self._M_cache

    def set_reference_to_current(self, model: pin.Model, data: pin.Data) -> None:
        """Set the reference placement to the frame's current placement (call when the contact is made)."""
        self.set_reference(self.placement(model, data))

    @property
    def reference(self) -> pin.SE3 | None:
        """The reference placement (a copy), or ``None`` before the first ``set_reference``."""
        return None if self._M_ref is None else pin.SE3(self._M_ref)

    # ------------------------------------------------------------------------------------------- contract
    def placement(self, model: pin.Model, data: pin.Data) -> pin.SE3:
        """Current placement ``T_world_frame`` (a copy)."""
        return pin.SE3(pin.updateFramePlacement(model, data, self._frame_id))

    def error(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``log6(T_world_frame^-1 T_world_ref)`` (or by ``error``), (6,), m and rad in the LOCAL frame."""
        if self._M_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the contact")
        return self._pose_error(pin.updateFramePlacement(model, data, self._frame_id))

    def _pose_error(self, oMf: pin.SE3) -> FloatArray:
        M = oMf.actInv(self._M_ref)
        if self._error_convention == "split":  # [R^T (p_ref - p); log3(R^T R_ref)]
            return np.concatenate([M.translation, pin.log3(M.rotation)])
        return pin.log6(M).vector

    def jacobian(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """LOCAL frame Jacobian (6, nv); also the wrench map ``J^T w`` of the dynamics."""
        return pin.getFrameJacobian(model, data, self._frame_id, _LOCAL)

    def velocity(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Local twist ``[v; omega]`` of the frame (6,), m/s and rad/s in the LOCAL frame."""
        return pin.getFrameVelocity(model, data, self._frame_id, _LOCAL).vector

    def drift(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``J_dot v`` in LOCAL (6,): the spatial (default) or classical acceleration of the frame at zero joint
        acceleration (``drift``)."""
        if self._drift == "classical":
            return pin.getFrameClassicalAcceleration(model, data, self._frame_id, _LOCAL).vector
        return pin.getFrameAcceleration(model, data, self._frame_id, _LOCAL).vector

    # stacked evaluation (see Task._write_jacobian): the contract's computations, one call less each
    def _write_jacobian(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        J = pin.getFrameJacobian(model, data, self._frame_id, _LOCAL)
        out[...] = J if self._all_selected else J[self._selection]

    def _write_error(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        if self._M_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the contact")
        e = self._pose_error(pin.updateFramePlacement(model, data, self._frame_id))
        out[...] = e if self._all_selected else e[self._selection]

    def _write_drift(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        if self._drift == "classical":
            a = pin.getFrameClassicalAcceleration(model, data, self._frame_id, _LOCAL).vector
        else:
            a = pin.getFrameAcceleration(model, data, self._frame_id, _LOCAL).vector
        out[...] = a if self._all_selected else a[self._selection]


def as_wrench_metric(metric: npt.ArrayLike) -> FloatArray:
    """``metric`` as a (6, 6) float array; ValueError unless it is finite, symmetric and positive semi-definite (to
    rounding)."""
    try:
        W = np.array(metric, dtype=np.float64)
    except (TypeError, ValueError):
        W = None
    if W is None or W.shape != (6, 6) or not np.all(np.isfinite(W)):
        raise ValueError("must be a finite 6 x 6 matrix (rows and columns fx fy fz tx ty tz)")
    scale = max(float(np.abs(W).max()), 1e-300)
    if np.abs(W - W.T).max() > 1e-12 * scale:
        raise ValueError("must be symmetric")
    if np.linalg.eigvalsh(0.5 * (W + W.T)).min() < -1e-12 * scale:
        raise ValueError("must be positive semi-definite")
    return W


def sole_corners(length: float, width: float, center: Sequence[float] = (0.0, 0.0)) -> FloatArray:
    """The 4 corners (4, 3) [m] of a ``length`` x ``width`` sole centred at ``center`` in its frame's x-y plane:
    (+x +y), (+x -y), (-x +y), (-x -y) (`Contact6D.corners`)."""
    hx, hy = 0.5 * length, 0.5 * width
    cx, cy = center
    return np.array([[cx + sx * hx, cy + sy * hy, 0.0] for sx in (1.0, -1.0) for sy in (1.0, -1.0)])


def tsid_wrench_metric(corners: npt.ArrayLike, *, weight: float, axis_weights: Sequence[float] =
                       TSID_WRENCH_AXIS_WEIGHTS, corner_regularization: float = 1e-8,
                       tsid_frame: pin.SE3 | None = None) -> FloatArray:
    """The (6, 6) metric on a 6D wrench (at a contact frame's origin, in its axes) equivalent to C++ TSID's
    regularisation of a ``Contact6d``, for `Contact6D`'s ``wrench_metric``.

    TSID's decision variables of a 6D contact are its four corner forces ``f`` (12,), the wrench
    ``w_T = G f`` (its force generator matrix, `Contact6D.corner_wrench_map`'s). Their cost is
    ``weight ||diag(a) w_T||^2`` (the force regularisation task, weight as given to ``addRigidContact``, ``a``
    its ``setRegularizationTaskWeightVector``, default (1, 1, 1e-3, 2, 2, 2)) plus its QP solver's Hessian
    regularisation ``eps ||f||^2`` on every variable (``eps`` = 1e-8 in TSID 1.7's solvers). For a given wrench
    ``w`` the cheapest corner forces are the least-norm ones, ``f = G^T (G G^T)^-1 w``, whose cost is
    ``eps w^T (G G^T)^-1 w``: the metric is

        ``W = weight X^T diag(a)^2 X + eps (G G^T)^-1``

    with ``G`` built from ``corners`` (4, 3) [m] given in this contact's frame, and ``X`` the map of a wrench at
    this frame to TSID's contact frame ``tsid_frame`` (its placement in this frame; None: the same frame): when
    TSID's frame is the ankle above the sole, ``X`` couples the sole's forces and the ankle's moments. The QP in
    ``w`` then has TSID's optimum whenever the least-norm corner forces are inside their friction pyramids (the
    cones of a contact hold the wrenches of corner forces inside them: then no cone row binds in either
    problem). TSID's ``mu`` is that of its corner pyramids: `Contact6D`'s ``mu`` is ``sqrt(2)`` times it (its
    pyramid is ``mu / sqrt(2)``).

    Args:
        corners: the four contact points (4, 3) [m] in this contact's frame (TSID's ``contactPoints``, moved to
            this frame, transposed).
        weight: TSID's force regularisation weight (``addRigidContact``'s), >= 0.
        axis_weights: TSID's per-axis weights ``a`` (6,), >= 0.
        corner_regularization: TSID's solver Hessian regularisation ``eps`` on each corner force, >= 0.
        tsid_frame: TSID's contact frame in this contact's frame, None: the same.
    """
    P = np.asarray(corners, dtype=np.float64)
    owner = "tsid_wrench_metric"
    if P.shape != (4, 3) or not np.all(np.isfinite(P)):
        raise TaskConfigError(owner, "corners", f"must be 4 finite points (4, 3) [m], got shape {P.shape}")
    a = val.as_vector(axis_weights, 6, owner, "axis_weights")
    if np.any(a < 0):
        raise TaskConfigError(owner, "axis_weights", f"must be >= 0, got {a.tolist()}")
    weight = val.as_scalar(weight, owner, "weight")
    eps = val.as_scalar(corner_regularization, owner, "corner_regularization")
    G = np.zeros((6, 12))
    for i, p in enumerate(P):
        G[:3, 3 * i:3 * i + 3] = np.eye(3)
        G[3:, 3 * i:3 * i + 3] = _skew(p)
    X = np.eye(6) if tsid_frame is None else tsid_frame.inverse().toDualActionMatrix()
    D = X.T @ np.diag(a**2) @ X
    W = weight * D + eps * np.linalg.inv(G @ G.T)
    return 0.5 * (W + W.T)
