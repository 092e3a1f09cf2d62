"""Least-squares similarity or rigid transform between two point sets (Umeyama 1991).

Given corresponding points ``source`` (n, d) and ``target`` (n, d), :func:`umeyama` finds ``s``, ``R``, ``t``
minimising ``sum_i w_i || target_i - (s R source_i + t) ||^2`` with ``R`` a proper rotation (det +1): when the
best orthogonal matrix is a reflection, the sign of the smallest singular direction is flipped (Umeyama's
``S = diag(1, ..., 1, -1)``), which gives the best rotation. With ``with_scale=False`` the transform is rigid
(``s = 1``). This is the algorithm of Eigen's ``umeyama`` used by paper 004 to align the suit's world frame to the
human model's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ...errors import WbcError

__all__ = ["AlignmentError", "SimilarityTransform", "UmeyamaResult", "umeyama"]

FloatArray = npt.NDArray[np.float64]


class AlignmentError(WbcError, ValueError):
    """The point sets cannot define a transform (too few points, degenerate, non-finite, mismatched)."""


@dataclass(frozen=True)
class SimilarityTransform:
    """``x -> scale * rotation @ x + translation``.

    Attributes:
        rotation: (d, d) proper rotation matrix.
        translation: (d,) [same unit as the points].
        scale: > 0 (1 for a rigid transform).
    """

    rotation: FloatArray
    translation: FloatArray
    scale: float = 1.0

    def apply(self, points: npt.ArrayLike) -> FloatArray:
        """Transform points (..., d)."""
        p = np.asarray(points, dtype=float)
        return self.scale * p @ self.rotation.T + self.translation

    def apply_rotation(self, rotations: npt.ArrayLike) -> FloatArray:
        """Rotate frames: ``rotation @ R`` for rotation matrices (..., d, d)."""
        return np.asarray(self.rotation) @ np.asarray(rotations, dtype=float)

    def inverse(self) -> "SimilarityTransform":
        """The inverse transform."""
        R_inv = self.rotation.T
        return SimilarityTransform(R_inv, -(R_inv @ self.translation) / self.scale, 1.0 / self.scale)

    def compose(self, other: "SimilarityTransform") -> "SimilarityTransform":
        """``self o other`` (apply ``other`` first)."""
        return SimilarityTransform(
            self.rotation @ other.rotation,
            self.scale * self.rotation @ other.translation + self.translation,
            self.scale * other.scale,
        )

    def as_se3(self) -> pin.SE3:
        """The rigid part as a ``pin.SE3`` (3-D only; the scale is dropped)."""
        if self.rotation.shape != (3, 3):
            raise ValueError("as_se3 needs a 3-D transform")
        return pin.SE3(np.array(self.rotation), np.array(self.translation))


@dataclass(frozen=True)
class UmeyamaResult:
    """Result of :func:`umeyama`.

    Attributes:
        transform: the estimated transform, source -> target.
        rms: root mean square residual ``sqrt(sum w_i ||target_i - T(source_i)||^2 / sum w_i)`` (point units).
        reflection_corrected: True when the unconstrained optimum was a reflection and was turned into the best
            proper rotation.
    """

    transform: SimilarityTransform
    rms: float
    reflection_corrected: bool


def umeyama(
    source: npt.ArrayLike,
    target: npt.ArrayLike,
    *,
    with_scale: bool = True,
    weights: npt.ArrayLike | None = None,
) -> UmeyamaResult:
    """Estimate the transform taking ``source`` (n, d) onto ``target`` (n, d) in the least-squares sense.

    Args:
        source, target: corresponding points, same shape (n, d), d >= 2, n >= d; rows containing NaN in either
            set are ignored.
        with_scale: estimate a similarity (True) or a rigid transform (False).
        weights: optional (n,) non-negative weights.

    Raises:
        AlignmentError: mismatched shapes, fewer than ``d`` usable points, all source points coincident, or a
            configuration too degenerate for a unique rotation (points on a line in 3-D).
    """
    src = np.asarray(source, dtype=float)
    dst = np.asarray(target, dtype=float)
    if src.ndim != 2 or src.shape != dst.shape or src.shape[1] < 2:
        raise AlignmentError(f"umeyama: expected two (n, d) arrays with d >= 2, got {src.shape} and {dst.shape}")
    d = src.shape[1]
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    if w.shape != (len(src),) or np.any(~np.isfinite(w)) or np.any(w < 0):
        raise AlignmentError(f"umeyama: weights must be {len(src)} finite values >= 0")
    usable = np.all(np.isfinite(src), axis=1) & np.all(np.isfinite(dst), axis=1) & (w > 0)
    src, dst, w = src[usable], dst[usable], w[usable]
    if len(src) < d:
        raise AlignmentError(f"umeyama: {len(src)} usable point pairs, at least {d} needed")
    w = w / w.sum()
    mu_src = w @ src
    mu_dst = w @ dst
    xs = src - mu_src
    xd = dst - mu_dst
    var_src = float(w @ np.sum(xs * xs, axis=1))
    if var_src <= 1e-18 * max(1.0, float(np.abs(src).max())) ** 2:
        raise AlignmentError("umeyama: the source points all coincide")
    sigma = (xd * w[:, None]).T @ xs  # (d, d) cross-covariance
    U, singular, Vt = np.linalg.svd(sigma)
    rank_tol = 1e-9 * max(singular[0], 1e-300)
    rank = int(np.sum(singular > rank_tol))
    if rank < d - 1:
        raise AlignmentError(
            f"umeyama: degenerate point sets (cross-covariance rank {rank} < {d - 1}): the rotation is not unique"
        )
    S = np.ones(d)
    reflection = bool(np.linalg.det(U) * np.linalg.det(Vt) < 0.0)
    if reflection:
        S[-1] = -1.0
    R = U @ np.diag(S) @ Vt
    scale = float(singular @ S / var_src) if with_scale else 1.0
    if with_scale and scale <= 0.0:
        raise AlignmentError("umeyama: the estimated scale is not positive (degenerate point sets)")
    t = mu_dst - scale * R @ mu_src
    transform = SimilarityTransform(R, t, scale)
    residual = dst - transform.apply(src)
    rms = float(np.sqrt(w @ np.sum(residual * residual, axis=1)))
    # "reflection corrected" only when it changed the answer, i.e. sigma itself is not rank deficient there
    return UmeyamaResult(transform, rms, reflection and singular[-1] > rank_tol)
