"""ZMP preview control on the cart-table model (Kajita et al., ICRA 2003), one horizontal axis at a time.

Cart-table, per axis, sampled at dt with the CoM jerk u held constant over each tick:

    x = (c, c_dot, c_ddot),   x[k+1] = A x[k] + B u[k],   p[k] = C x[k] = c - (c_z / g) c_ddot

LQ with integral action (Katayama et al. 1985, as in Kajita 2003): minimise
sum_k Qe (p[k] - p_ref[k])^2 + R u[k]^2 over the augmented state (e[k], x[k] - x[k-1]); the optimal law is

    u[k] = -Gi sum_{i<=k} (p[i] - p_ref[i]) - Gx x[k] - sum_{j=1..N} Gd[j] p_ref[k + j]

with N = horizon / dt. The discrete algebraic Riccati equation is badly conditioned at 1 kHz (condition number
of its solution about 4e10 with R = 1e-6, 4e12 with R = 1e-8), so `preview_gains` does not trust
scipy.linalg.solve_discrete_are blindly: it refines the solution with Newton (Hewer) steps, each solving a
Stein equation for the closed loop in coordinates scaled by diag(P)^(-1/2) (unscaled, that 16 x 16 system is
itself near singular below 1 ms), and raises PreviewControlError if the refinement moves the feedback gains
by more than 1e-6 relative, the scaled Riccati residual exceeds 1e-8, or the closed loop is not stable. At
1 ms the gains move by about 1e-11 and the residual is about 1e-15; `tests/planning` also compares a 1 ms plan
with a 5 ms plan evaluated exactly at 1 kHz (`PatternGeneratorConfig.preview_dt`).

The simulation runs in coordinates relative to the first reference sample: the truncated preview sum is not
translation invariant (sum Gd != -Gx[0] for a finite horizon), so a robot at rest on a constant reference
stays exactly at rest only in those coordinates.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from ..errors import PlanningError
from ..types import GRAVITY

__all__ = ["PreviewControlError", "PreviewGains", "preview_gains", "simulate_preview", "cart_table"]


class PreviewControlError(ArithmeticError):
    """The preview-control gains could not be computed accurately."""


def cart_table(dt: float, com_height: float, gravity: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete cart-table model with piecewise-constant jerk.

    Returns:
        A (3, 3), B (3,), C (3,): x[k+1] = A x[k] + B u[k], ZMP p = C x, for x = (c [m], c_dot [m/s],
        c_ddot [m/s^2]) and u the jerk [m/s^3].
    """
    A = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    B = np.array([dt**3 / 6.0, 0.5 * dt * dt, dt])
    C = np.array([1.0, 0.0, -com_height / gravity])
    return A, B, C


@dataclass(frozen=True, eq=False)
class PreviewGains:
    """Preview-control gains for one sampling period and CoM height.

    Attributes:
        dt: sampling period [s]. com_height: c_z above the ZMP plane [m]. gravity: [m/s^2].
        horizon: preview horizon [s]. zmp_weight: Qe [1/m^2]. jerk_weight: R [s^6/m^2].
        A, B, C: the cart-table model (see `cart_table`).
        Gi: integral gain [1/s^3 per m summed per tick]. Gx: state gains, shape (3,).
        Gd: preview gains, shape (N,); Gd[j - 1] multiplies p_ref[k + j].
        riccati_residual: residual of the refined Riccati equation, max |D res D| with D = diag(P)^(-1/2)
            (relative to a solution with unit diagonal).
        refinement_change: relative change of the feedback gains under Newton refinement.
        spectral_radius: largest closed-loop eigenvalue modulus (< 1).
    """

    dt: float
    com_height: float
    gravity: float
    horizon: float
    zmp_weight: float
    jerk_weight: float
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Gi: float
    Gx: np.ndarray
    Gd: np.ndarray
    riccati_residual: float
    refinement_change: float
    spectral_radius: float


def _check_positive(name: str, value: float) -> float:
    if not np.isfinite(value) or value <= 0.0:
        raise PlanningError(f"{name} must be positive and finite, got {value!r}")
    return float(value)


def preview_gains(dt: float, com_height: float, gravity: float = GRAVITY, horizon: float = 2.5,
                  zmp_weight: float = 1.0, jerk_weight: float = 1e-8) -> PreviewGains:
    """Solve and check the preview-control LQ problem (cached on its arguments).

    Args:
        dt: sampling period [s].
        com_height: CoM height above the ZMP plane [m].
        gravity: [m/s^2], positive.
        horizon: preview horizon [s]; tracking error grows quickly below about 2 s for c_z = 0.87 m.
        zmp_weight, jerk_weight: Qe and R of the cost.

    Raises:
        ValueError: non-positive arguments or a horizon shorter than one tick.
        PreviewControlError: the Riccati solution fails the accuracy checks.
    """
    args = tuple(_check_positive(n, v) for n, v in (("dt", dt), ("com_height", com_height),
                                                   ("gravity", gravity), ("horizon", horizon),
                                                   ("zmp_weight", zmp_weight), ("jerk_weight", jerk_weight)))
    if horizon < dt:
        raise PlanningError(f"horizon ({horizon} s) must be at least one tick ({dt} s)")
    return _preview_gains(*args)


@functools.lru_cache(maxsize=32)
def _preview_gains(dt: float, com_height: float, gravity: float, horizon: float, zmp_weight: float,
                   jerk_weight: float) -> PreviewGains:
    A, B, C = cart_table(dt, com_height, gravity)
    # Augmented system on (e[k], x[k] - x[k-1]).
    Aa = np.zeros((4, 4))
    Aa[0, 0] = 1.0
    Aa[0, 1:] = C @ A
    Aa[1:, 1:] = A
    Ba = np.concatenate([[C @ B], B]).reshape(4, 1)
    Q = np.zeros((4, 4))
    Q[0, 0] = zmp_weight
    R = np.array([[jerk_weight]])

    def gain(P: np.ndarray) -> np.ndarray:
        return np.linalg.solve(R + Ba.T @ P @ Ba, Ba.T @ P @ Aa)

    try:
        P = scipy.linalg.solve_discrete_are(Aa, Ba, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise PreviewControlError(f"Riccati solve failed at dt={dt} s, c_z={com_height} m: {exc}") from None
    K0 = gain(P)
    # Newton (Hewer) refinement: P = Acl^T P Acl + Q + K^T R K for the current K, then K from P.
    # The Stein equations are solved in coordinates scaled by D = diag(P)^(-1/2), where the solution has a
    # unit diagonal: without it the 16 x 16 linear system is near singular below 1 ms.
    d = 1.0 / np.sqrt(np.abs(np.diag(P)))
    K = K0
    for _ in range(3):
        Acl = Aa - Ba @ K
        if np.max(np.abs(np.linalg.eigvals(Acl))) >= 1.0:
            raise PreviewControlError(f"preview control closed loop unstable at dt={dt} s, c_z={com_height} m")
        A_scaled = Acl / d[:, None] * d[None, :]  # D^-1 Acl D
        Q_scaled = (Q + K.T @ R @ K) * d[:, None] * d[None, :]  # D Q D
        P_scaled = scipy.linalg.solve_discrete_lyapunov(A_scaled.T, Q_scaled)
        P = P_scaled / d[:, None] / d[None, :]
        P = 0.5 * (P + P.T)
        K = gain(P)
    change = float(np.max(np.abs(K - K0)) / np.max(np.abs(K0)))
    residual = Aa.T @ P @ Aa - P - Aa.T @ P @ Ba @ K + Q
    # Relative residual in the scaled coordinates (where P has a unit diagonal), so small entries count too.
    rel_residual = float(np.max(np.abs(residual * d[:, None] * d[None, :])))
    Acl = Aa - Ba @ K
    rho = float(np.max(np.abs(np.linalg.eigvals(Acl))))
    if not (change < 1e-6 and rel_residual < 1e-8 and rho < 1.0):
        raise PreviewControlError(
            f"inaccurate preview gains at dt={dt} s, c_z={com_height} m: gain change under refinement "
            f"{change:.2e}, relative Riccati residual {rel_residual:.2e}, closed-loop spectral radius {rho:.6f}; "
            "use a coarser preview_dt")
    S = float((R + Ba.T @ P @ Ba)[0, 0])
    n = int(round(horizon / dt))
    Gd = np.empty(n)
    Gd[0] = -K[0, 0]
    X = -Acl.T @ P[:, 0]
    for j in range(1, n):
        Gd[j] = float(Ba[:, 0] @ X) / S
        X = Acl.T @ X
    Gx = K[0, 1:].copy()
    for a in (A, B, C, Gx, Gd):
        a.flags.writeable = False
    return PreviewGains(dt, com_height, gravity, horizon, zmp_weight, jerk_weight, A, B, C, float(K[0, 0]), Gx,
                        Gd, rel_residual, change, rho)


def simulate_preview(gains: PreviewGains, zmp_ref: np.ndarray, x0: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Run the preview controller along a known ZMP reference.

    Past the last sample the reference is taken as constant (the plan ends at rest).

    Args:
        gains: from `preview_gains`.
        zmp_ref: ZMP reference per tick, shape (n,) or (n, d) for d independent axes [m].
        x0: initial (c, c_dot, c_ddot), shape (3,) or (3, d); default at rest on zmp_ref[0].

    Returns:
        states: (c, c_dot, c_ddot) per tick, shape (n, 3) or (n, 3, d), states[0] = x0.
        jerk: applied jerk per tick [m/s^3], shape (n,) or (n, d); states[k+1] = A states[k] + B jerk[k].
    """
    ref = np.asarray(zmp_ref, dtype=float)
    vector = ref.ndim == 1
    if vector:
        ref = ref[:, None]
    if ref.ndim != 2 or len(ref) == 0 or not np.all(np.isfinite(ref)):
        raise PlanningError("zmp_ref must be a non-empty finite array of shape (n,) or (n, d)")
    n, d = ref.shape
    origin = ref[0].copy()
    if x0 is None:
        x = np.zeros((3, d))
    else:
        x = np.array(x0, dtype=float).reshape(3, -1) * np.ones((3, d))
        x[0] -= origin
    r = ref - origin
    N = len(gains.Gd)
    padded = np.concatenate([r, np.repeat(r[-1:], N, axis=0)])
    # Direct (not FFT) correlation: a constant reference gives exactly zero preview action.
    preview = np.column_stack([np.correlate(padded[1:, i], gains.Gd, mode="valid") for i in range(d)])
    A, B, C = gains.A, gains.B, gains.C
    Gi, (g0, g1, g2) = gains.Gi, gains.Gx
    a01, a02, a12 = A[0, 1], A[0, 2], A[1, 2]
    b0, b1, b2 = B
    c0, c2 = C[0], C[2]
    states = np.empty((n, 3, d))
    jerk = np.empty((n, d))
    for i in range(d):
        c, v, a = (float(s) for s in x[:, i])
        rr = r[:, i].tolist()
        ff = preview[:, i].tolist()
        out = np.empty((n, 3))
        uu = np.empty(n)
        integral = 0.0
        for k in range(n):
            out[k] = (c, v, a)
            integral += c0 * c + c2 * a - rr[k]
            u = -Gi * integral - (g0 * c + g1 * v + g2 * a) - ff[k]
            uu[k] = u
            c, v, a = c + a01 * v + a02 * a + b0 * u, v + a12 * a + b1 * u, a + b2 * u
        states[:, :, i] = out
        jerk[:, i] = uu
    states[:, 0, :] += origin
    if vector:
        return states[:, :, 0], jerk[:, 0]
    return states, jerk
