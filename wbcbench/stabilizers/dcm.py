"""DCM PI control and CoM admittance: the stabilizer of the position-controlled schemes (IK, TSID position).

Paper 000 (Ramuzat et al. 2022), Section 2.1, after Caron et al. (2019), "Stair climbing stabilization of the
HRP-4 humanoid robot using whole-body admittance control":

    Eq. 2   omega = sqrt(g / c_z),   xi = c + c_dot / omega                                   (DCM)
    Eq. 3   z* = z_ref - (1 + kp_dcm / omega)(xi_ref - xi) + (kz_dcm / omega)(z_ref - z)
                 - (ki_dcm / omega) * integral(xi_ref - xi) dt                                (DCM PI -> ZMP)
    Eq. 4   c_ddot* = c_ddot_ref + kp_adm (z - z*)                                              (CoM admittance)

z is the measured ZMP, xi the measured DCM, both horizontal (x, y). The stabilizer turns c_ddot* into a
corrected CoM reference by integrating, tick by tick, the difference c_ddot* - c_ddot_ref into an offset
added to the planned CoM (position, velocity); this is the double integration of c_ddot* started on the
reference, so a reference followed exactly passes through unchanged. The CoM height passes through.

As in the TALOS balance stack (sot-talos-balance), the integral is updated after it is used, and the output
position is the one reached at the end of the tick under c_ddot*. Extras, all optional: a first-order
low-pass on the measured ZMP (cut-off in Hz; SIM-NOTES: 20 Hz made the torque-mode loop stable, 5 Hz broke
the position-mode one, so it is off by default), a clamp on the DCM error integral (anti-windup), a leak on
that integral, and a clamp on the CoM offset.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..jit import njit
from ..types import GRAVITY

__all__ = [
    "natural_frequency",
    "dcm_from_com",
    "dcm_pi_zmp",
    "com_admittance",
    "DcmGains",
    "IK_GAINS",
    "IK_STAIRS_GAINS",
    "TSID_POSITION_GAINS",
    "PAPER_GAINS",
    "FirstOrderLowPass",
    "DcmStabilizerOutput",
    "DcmStabilizer",
]


# ---- the laws ----------------------------------------------------------------------------------------------
def natural_frequency(com_height: float, gravity: float = GRAVITY) -> float:
    """omega = sqrt(g / c_z) [1/s] of the linear inverted pendulum (paper Eq. 2)."""
    if not np.isfinite(com_height) or com_height <= 0.0 or not np.isfinite(gravity) or gravity <= 0.0:
        raise ValueError(f"com_height and gravity must be positive, got {com_height!r}, {gravity!r}")
    return float(np.sqrt(gravity / com_height))


def dcm_from_com(p_com: np.ndarray, v_com: np.ndarray, omega: float) -> np.ndarray:
    """Divergent component of motion xi = c + c_dot / omega (paper Eq. 2). Shapes follow the inputs [m]."""
    return np.asarray(p_com, float) + np.asarray(v_com, float) / omega


def dcm_pi_zmp(p_zmp_ref: np.ndarray, dcm_ref: np.ndarray, dcm_measured: np.ndarray, p_zmp_measured: np.ndarray,
               dcm_error_integral: np.ndarray, omega: float, kp_dcm: float, ki_dcm: float, kz_dcm: float
               ) -> np.ndarray:
    """Desired ZMP from the DCM PI controller (paper Eq. 3, Caron et al. 2019).

    z* = z_ref - (1 + kp_dcm / omega)(xi_ref - xi) + (kz_dcm / omega)(z_ref - z) - (ki_dcm / omega) I,
    with I the integral of (xi_ref - xi) [m s]. All vectors horizontal, same shape, [m]; kp_dcm and kz_dcm
    [1/s], ki_dcm [1/s^2], omega [1/s].
    """
    dcm_error = np.asarray(dcm_ref, float) - np.asarray(dcm_measured, float)
    zmp_ref = np.asarray(p_zmp_ref, float)
    zmp_error = zmp_ref - np.asarray(p_zmp_measured, float)
    return (zmp_ref - (1.0 + kp_dcm / omega) * dcm_error + (kz_dcm / omega) * zmp_error
            - (ki_dcm / omega) * np.asarray(dcm_error_integral, float))


def com_admittance(a_com_ref: np.ndarray, p_zmp_measured: np.ndarray, p_zmp_desired: np.ndarray, kp_adm: float
                   ) -> np.ndarray:
    """Commanded CoM acceleration c_ddot* = c_ddot_ref + kp_adm (z - z*) (paper Eq. 4) [m/s^2]; kp_adm [1/s^2]."""
    zmp_error = np.asarray(p_zmp_measured, float) - np.asarray(p_zmp_desired, float)
    return np.asarray(a_com_ref, float) + kp_adm * zmp_error


# ---- gains -------------------------------------------------------------------------------------------------
def _check(owner: str, name: str, value: float | None, *, optional: bool = False, positive: bool = False) -> None:
    if value is None and optional:
        return
    if value is None or isinstance(value, bool) or not np.isfinite(value) or value < 0.0 or (positive and value == 0.0):
        kind = "positive" if positive else "non-negative"
        raise ValueError(f"{owner}.{name} must be a {kind} finite number{' or None' if optional else ''}, "
                         f"got {value!r}")


@dataclass(frozen=True)
class DcmGains:
    """Gains of the DCM PI controller and the CoM admittance (paper Table 1); defaults: the IK column.

    Attributes:
        kp_adm: CoM admittance gain [1/s^2] (Eq. 4).
        kp_dcm: DCM proportional gain [1/s] (Eq. 3).
        ki_dcm: DCM integral gain [1/s^2] (Eq. 3).
        kz_dcm: ZMP feedback gain [1/s] (Eq. 3).
        integral_limit: clamp on each axis of the DCM error integral [m s] (anti-windup); None: no clamp.
        integral_leak: leak rate of that integral [1/s]: I += (e - leak I) dt (0: pure integral).
        zmp_cutoff_hz: cut-off of a first-order low-pass on the measured ZMP [Hz]; None: unfiltered.
        com_offset_limit: clamp on each horizontal axis of the corrected-minus-planned CoM [m]; None: no clamp.
    """

    kp_adm: float = 15.0
    kp_dcm: float = 8.0
    ki_dcm: float = 1.0
    kz_dcm: float = 1.0
    integral_limit: float | None = 0.1
    integral_leak: float = 0.0
    zmp_cutoff_hz: float | None = None
    com_offset_limit: float | None = None

    def __post_init__(self) -> None:
        for name in ("kp_adm", "kp_dcm", "ki_dcm", "kz_dcm", "integral_leak"):
            _check("DcmGains", name, getattr(self, name))
        for name in ("integral_limit", "zmp_cutoff_hz", "com_offset_limit"):
            _check("DcmGains", name, getattr(self, name), optional=True, positive=True)


IK_GAINS = DcmGains(kp_adm=15.0, kp_dcm=8.0, ki_dcm=1.0, kz_dcm=1.0)
"""Paper Table 1, IK, walking (20 cm)."""
IK_STAIRS_GAINS = DcmGains(kp_adm=45.0, kp_dcm=25.0, ki_dcm=1.0, kz_dcm=1.0)
"""Paper Table 1, IK, stairs."""
TSID_POSITION_GAINS = DcmGains(kp_adm=12.0, kp_dcm=8.0, ki_dcm=1.0, kz_dcm=1.0)
"""Paper Table 1, TSID position."""
PAPER_GAINS: dict[str, DcmGains] = {
    "ik": IK_GAINS,
    "ik_stairs": IK_STAIRS_GAINS,
    "tsid_position": TSID_POSITION_GAINS,
}
"""The paper's gain sets by name (the TSID torque scheme has no stabilizer)."""


# ---- filter ------------------------------------------------------------------------------------------------
class FirstOrderLowPass:
    """y += alpha (u - y), alpha = 1 - exp(-2 pi f_c dt): the exact discretisation of 1 / (1 + s / (2 pi f_c)).

    The first sample after a reset initialises the output (no start-up transient).
    """

    def __init__(self, cutoff_hz: float, dt: float):
        _check("FirstOrderLowPass", "cutoff_hz", cutoff_hz, positive=True)
        _check("FirstOrderLowPass", "dt", dt, positive=True)
        self.cutoff_hz = float(cutoff_hz)
        self.dt = float(dt)
        self.alpha = float(1.0 - np.exp(-2.0 * np.pi * cutoff_hz * dt))
        self._y: np.ndarray | None = None

    def reset(self) -> None:
        self._y = None

    def __call__(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, float)
        self._y = u.copy() if self._y is None else self._y + self.alpha * (u - self._y)
        return self._y.copy()


# ---- stateful stabilizer -----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class DcmStabilizerOutput:
    """One stabilizer tick (world frame).

    Attributes:
        p_world_com: corrected CoM reference [m], (3,) (z: the planned one).
        v_world_com: corrected CoM velocity [m/s], (3,).
        a_world_com: commanded CoM acceleration c_ddot* [m/s^2], (3,) (Eq. 4; z: the planned one).
        p_world_zmp_desired: z* of Eq. 3 [m], (2,).
        p_world_zmp_measured: the measured ZMP after the optional low-pass [m], (2,).
        p_world_dcm: measured DCM [m], (2,).
        p_world_dcm_ref: planned DCM [m], (2,).
        dcm_error_integral: integral of (xi_ref - xi) after this tick's update [m s], (2,).
        integral_saturated: which axes hit integral_limit this tick, (2,) bool.
    """

    p_world_com: np.ndarray
    v_world_com: np.ndarray
    a_world_com: np.ndarray
    p_world_zmp_desired: np.ndarray
    p_world_zmp_measured: np.ndarray
    p_world_dcm: np.ndarray
    p_world_dcm_ref: np.ndarray
    dcm_error_integral: np.ndarray
    integral_saturated: np.ndarray


def _vec(name: str, value: np.ndarray, sizes: tuple[int, ...]) -> np.ndarray:
    """A flat float array of one of the allowed sizes (finiteness is checked by the caller, once)."""
    v = np.asarray(value, dtype=float).ravel()
    if v.size not in sizes:
        raise ValueError(f"{name} must have {' or '.join(map(str, sizes))} elements, got shape {np.shape(value)}")
    return v


class DcmStabilizer:
    """DCM PI + CoM admittance (paper Eq. 3-4) with its state: the DCM error integral, the CoM offset, the filter.

    Args:
        gains: the gain set (e.g. IK_GAINS, TSID_POSITION_GAINS).
        dt: control period [s].
        com_height: nominal CoM height for omega [m].
        gravity: [m/s^2].

    A new stabilizer starts reset; call `reset()` whenever the control loop restarts.
    """

    def __init__(self, gains: DcmGains, *, dt: float, com_height: float, gravity: float = GRAVITY):
        if not isinstance(gains, DcmGains):
            raise ValueError(f"gains must be DcmGains, got {type(gains).__name__}")
        _check("DcmStabilizer", "dt", dt, positive=True)
        self.gains = gains
        self.dt = float(dt)
        self.omega = natural_frequency(com_height, gravity)
        self._filter = FirstOrderLowPass(gains.zmp_cutoff_hz, dt) if gains.zmp_cutoff_hz is not None else None
        # `_step`'s constants (13) and state (8) in one array (`_arrays`; `_constants`, `_state` views of it): one
        # argument of a compiled call that runs the step (stabilizers/balance.py)
        self._arrays = np.zeros(21)
        self._constants, self._state = self._arrays[:13], self._arrays[13:]
        # the constants: the gains, with the optional ones' switches (0 / 1), the filter's alpha, omega, dt
        g = gains
        self._constants[:] = np.array([
            g.kp_adm, g.kp_dcm, g.ki_dcm, g.kz_dcm, g.integral_leak,
            g.integral_limit is not None, g.integral_limit or 0.0,
            g.com_offset_limit is not None, g.com_offset_limit or 0.0,
            self._filter is not None, self._filter.alpha if self._filter is not None else 0.0,
            self.omega, self.dt])
        self.reset()

    def reset(self) -> None:
        """Zero the DCM error integral and the CoM offset, and restart the ZMP filter."""
        # the state, updated in place tick after tick: the integral (2), the CoM offset's position (2) and velocity
        # (2), the ZMP filter's last output (2; `_fresh`: none yet)
        self._state[:] = 0.0
        self._fresh = True
        if self._filter is not None:
            self._filter.reset()

    @property
    def dcm_error_integral(self) -> np.ndarray:
        """Current integral of (xi_ref - xi) [m s], (2,)."""
        return self._state[0:2].copy()

    @property
    def com_offset(self) -> np.ndarray:
        """Current corrected-minus-planned CoM position [m], (2,)."""
        return self._state[2:4].copy()

    def step(self, *, p_com_ref: np.ndarray, v_com_ref: np.ndarray, a_com_ref: np.ndarray, p_zmp_ref: np.ndarray,
             p_com: np.ndarray, v_com: np.ndarray, p_zmp: np.ndarray) -> DcmStabilizerOutput:
        """One tick of the stabilizer.

        Args:
            p_com_ref, v_com_ref, a_com_ref: planned CoM position [m], velocity [m/s], acceleration [m/s^2], (3,).
            p_zmp_ref: planned ZMP [m], (2,) or (3,) (x, y used).
            p_com, v_com: measured (estimated) CoM position and velocity, (3,) or (2,) (x, y used).
            p_zmp: measured ZMP [m], (2,) or (3,) (x, y used).

        Returns:
            The corrected CoM reference and the intermediate quantities.

        Raises:
            ValueError: wrong shapes or non-finite inputs.
        """
        args = (p_com_ref, v_com_ref, a_com_ref, p_zmp_ref, p_com, v_com, p_zmp)
        if all(type(x) is np.ndarray and x.dtype == np.float64 and x.ndim == 1 for x in args) and \
                p_com_ref.size == v_com_ref.size == a_com_ref.size == 3 and \
                all(x.size in (2, 3) for x in args[3:]):
            return self._step_compiled(*args)
        return self._step_numpy(*args)

    def _step_compiled(self, c_ref, v_ref, a_ref, z_ref, c, v, z) -> DcmStabilizerOutput:
        """`step` by `_dcm_step` (the same operations in the same order: the same numbers), for float64 vectors
        of the right sizes; its outputs are views of one new array."""
        out = self.step_array(c_ref, v_ref, a_ref, z_ref, c, v, z)
        return DcmStabilizerOutput(out[0:3], out[3:6], out[6:9], out[9:11], out[11:13], out[13:15], out[15:17],
                                   self._state[0:2].copy(), out[17:19] != 0.0)

    def step_array(self, c_ref, v_ref, a_ref, z_ref, c, v, z, log: np.ndarray | None = None) -> np.ndarray:
        """`step` for float64 1-D arrays of the sizes `step` takes (not checked here), its outputs in one new
        array (20,): CoM position, velocity, acceleration (3 each), z*, filtered measured ZMP, measured DCM,
        planned DCM (2 each), integral saturated (2, 0 / 1). `log` (6,), if given: measured ZMP, z*, measured
        DCM written there. A non-finite input raises as `step` does."""
        out = np.empty(20)
        state = self._state
        if log is None:
            done = _dcm_step(c_ref, v_ref, a_ref, z_ref, c, v, z, self._constants, self._fresh, state, out)
        else:
            done = _dcm_step_logged(c_ref, v_ref, a_ref, z_ref, c, v, z, self._constants, self._fresh, state, out,
                                    log)
        if not done:
            self._step_numpy(c_ref, v_ref, a_ref, z_ref, c, v, z)  # raises, naming the bad input
        if self._filter is not None:
            self._fresh = False
        return out

    def _step_numpy(self, p_com_ref, v_com_ref, a_com_ref, p_zmp_ref, p_com, v_com, p_zmp) -> DcmStabilizerOutput:
        """`step` for any array-likes (validated)."""
        g = self.gains
        c_ref = _vec("p_com_ref", p_com_ref, (3,))
        v_ref = _vec("v_com_ref", v_com_ref, (3,))
        a_ref = _vec("a_com_ref", a_com_ref, (3,))
        z_ref = _vec("p_zmp_ref", p_zmp_ref, (2, 3))[:2]
        c = _vec("p_com", p_com, (2, 3))[:2]
        v = _vec("v_com", v_com, (2, 3))[:2]
        z = _vec("p_zmp", p_zmp, (2, 3))[:2]
        if not np.isfinite(c_ref.sum() + v_ref.sum() + a_ref.sum() + z_ref.sum() + c.sum() + v.sum() + z.sum()):
            names = ("p_com_ref", "v_com_ref", "a_com_ref", "p_zmp_ref", "p_com", "v_com", "p_zmp")
            bad = [n for n, x in zip(names, (c_ref, v_ref, a_ref, z_ref, c, v, z)) if not np.all(np.isfinite(x))]
            raise ValueError(f"DcmStabilizer.step: non-finite input(s): {', '.join(bad)}")
        state = self._state
        if self._filter is not None:
            self._filter._y = None if self._fresh else state[6:8].copy()  # as the compiled path left it
            z = self._filter(z)
            state[6:8] = z
            self._fresh = False
        integral, offset_p, offset_v = state[0:2].copy(), state[2:4].copy(), state[4:6].copy()
        omega, dt = self.omega, self.dt
        xi_ref = dcm_from_com(c_ref[:2], v_ref[:2], omega)
        xi = dcm_from_com(c, v, omega)
        z_star = dcm_pi_zmp(z_ref, xi_ref, xi, z, integral, omega, g.kp_dcm, g.ki_dcm, g.kz_dcm)
        a_star = com_admittance(a_ref[:2], z, z_star, g.kp_adm)
        # Integrate c_ddot* relative to the plan: offset'' = c_ddot* - c_ddot_ref.
        da = a_star - a_ref[:2]
        offset_p = offset_p + (offset_v + (0.5 * dt) * da) * dt
        offset_v = offset_v + da * dt
        if g.com_offset_limit is not None:
            lim = g.com_offset_limit
            clipped = np.abs(offset_p) > lim
            if clipped.any():
                offset_p = np.clip(offset_p, -lim, lim)
                offset_v = np.where(clipped & (offset_v * offset_p > 0.0), 0.0, offset_v)
        # Integral update after use (optional leak, anti-windup clamp).
        error = xi_ref - xi
        if g.integral_leak:
            error = error - g.integral_leak * integral
        integral = integral + error * dt
        saturated = np.zeros(2, bool)
        if g.integral_limit is not None:
            saturated = np.abs(integral) >= g.integral_limit
            if saturated.any():
                integral = np.clip(integral, -g.integral_limit, g.integral_limit)
        state[0:2], state[2:4], state[4:6] = integral, offset_p, offset_v
        p_out = c_ref.copy()
        v_out = v_ref.copy()
        a_out = a_ref.copy()
        p_out[:2] += offset_p
        v_out[:2] += offset_v
        a_out[:2] = a_star
        return DcmStabilizerOutput(p_out, v_out, a_out, z_star, z, xi, xi_ref, integral.copy(), saturated)


@njit(exact=True)
def _finite(x, n):
    """Whether the first ``n`` entries of ``x`` are finite."""
    for i in range(n):
        if not np.isfinite(x[i]):
            return False
    return True


@njit(exact=True, inline=True)
def _dcm_step(c_ref, v_ref, a_ref, z_ref, c, v, z, k, fresh, state, out):
    """`DcmStabilizer.step`'s arithmetic, element by element in the numpy code's order. ``k``: the
    stabilizer's `_constants`; ``state`` (8,): integral, CoM offset position, velocity, the ZMP filter's last
    output (``fresh``: none yet), updated in place; ``out`` (20,): CoM position, velocity, acceleration (3 each),
    z*, filtered measured ZMP, measured DCM, planned DCM (2 each), integral saturated (2, 0 / 1). Returns False
    (nothing changed) when an input is not finite. Inlined: its compiled callers are all `exact`, as it is."""
    if not (_finite(c_ref, 3) and _finite(v_ref, 3) and _finite(a_ref, 3) and _finite(z_ref, 2) and _finite(c, 2)
            and _finite(v, 2) and _finite(z, 2)):
        return False
    kp_adm, kp_dcm, ki_dcm, kz_dcm, leak = k[0], k[1], k[2], k[3], k[4]
    omega, dt = k[11], k[12]
    for i in range(2):
        zi = z[i]
        if k[9] != 0.0:  # the ZMP's low-pass: y += alpha (u - y), the first sample as it is
            zi = zi if fresh else state[6 + i] + k[10] * (zi - state[6 + i])
            state[6 + i] = zi
        xi_ref = c_ref[i] + v_ref[i] / omega
        xi = c[i] + v[i] / omega
        err = xi_ref - xi
        z_star = (z_ref[i] - (1.0 + kp_dcm / omega) * err + (kz_dcm / omega) * (z_ref[i] - zi)
                  - (ki_dcm / omega) * state[i])
        a_star = a_ref[i] + kp_adm * (zi - z_star)
        da = a_star - a_ref[i]
        p = state[2 + i] + (state[4 + i] + (0.5 * dt) * da) * dt
        vel = state[4 + i] + da * dt
        out[6 + i] = a_star
        out[9 + i] = z_star
        out[11 + i] = zi
        out[13 + i] = xi
        out[15 + i] = xi_ref
        state[2 + i] = p
        state[4 + i] = vel
        if leak != 0.0:
            err = err - leak * state[i]
        state[i] = state[i] + err * dt
    if k[7] != 0.0:  # the CoM offset's clamp; a clamped axis moving outwards stops
        lim = k[8]
        if abs(state[2]) > lim or abs(state[3]) > lim:
            for i in range(2):
                clipped = abs(state[2 + i]) > lim
                state[2 + i] = min(max(state[2 + i], -lim), lim)
                if clipped and state[4 + i] * state[2 + i] > 0.0:
                    state[4 + i] = 0.0
    out[17] = out[18] = 0.0
    if k[5] != 0.0:  # anti-windup
        lim = k[6]
        for i in range(2):
            if abs(state[i]) >= lim:
                out[17 + i] = 1.0
        if out[17] != 0.0 or out[18] != 0.0:
            for i in range(2):
                state[i] = min(max(state[i], -lim), lim)
    for i in range(3):
        out[i] = c_ref[i]
        out[3 + i] = v_ref[i]
        out[6 + i] = out[6 + i] if i < 2 else a_ref[i]
    for i in range(2):
        out[i] += state[2 + i]
        out[3 + i] += state[4 + i]
    return True


@njit(exact=True, inline=True)
def _dcm_step_logged(c_ref, v_ref, a_ref, z_ref, c, v, z, k, fresh, state, out, log):
    """`_dcm_step`, then ``log`` (6,) = the filtered measured ZMP, z*, the measured DCM (x, y each) when it
    succeeded. Inlined: its compiled callers are all `exact`, as it is."""
    if not _dcm_step(c_ref, v_ref, a_ref, z_ref, c, v, z, k, fresh, state, out):
        return False
    log[0], log[1] = out[11], out[12]
    log[2], log[3] = out[9], out[10]
    log[4], log[5] = out[13], out[14]
    return True
