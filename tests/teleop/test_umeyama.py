"""Umeyama alignment: known transforms recovered with and without noise, reflections, degenerate sets."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from wbcbench.teleop import AlignmentError, SimilarityTransform, umeyama

SEEDS = st.integers(0, 2**32 - 1)


def _draw(seed: int, n: int = 15):
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=rng.integers(2**31)).as_matrix()
    t = rng.uniform(-3, 3, size=3)
    s = float(rng.uniform(0.3, 3.0))
    points = rng.normal(scale=0.5, size=(n, 3))
    return rng, R, t, s, points


@settings(max_examples=50, deadline=None)
@given(seed=SEEDS, with_scale=st.booleans())
def test_exact_transforms_are_recovered(seed, with_scale):
    _, R, t, s, src = _draw(seed)
    s = s if with_scale else 1.0
    dst = s * src @ R.T + t
    result = umeyama(src, dst, with_scale=with_scale)
    np.testing.assert_allclose(result.transform.rotation, R, atol=1e-9)
    np.testing.assert_allclose(result.transform.translation, t, atol=1e-9)
    assert result.transform.scale == pytest.approx(s, rel=1e-9)
    assert result.rms < 1e-9 and not result.reflection_corrected
    assert np.linalg.det(result.transform.rotation) == pytest.approx(1.0)


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS, noise=st.floats(1e-4, 2e-2))
def test_noisy_transforms_are_recovered_within_the_noise(seed, noise):
    rng, R, t, s, src = _draw(seed, n=60)
    dst = s * src @ R.T + t + rng.normal(scale=noise, size=src.shape)
    result = umeyama(src, dst)
    angle = np.linalg.norm(Rotation.from_matrix(result.transform.rotation @ R.T).as_rotvec())
    # error bounds: a few noise standard deviations over the cloud's extent (0.5) and sqrt(n)
    assert angle < 10 * noise / (0.5 * s)
    assert result.transform.scale == pytest.approx(s, abs=10 * noise)
    assert np.linalg.norm(result.transform.translation - t) < 10 * noise * (1 + s)
    assert result.rms == pytest.approx(noise * np.sqrt(3), rel=0.5)
    # the estimate is a least-squares optimum: the true transform does not fit better
    truth = SimilarityTransform(R, t, s)
    true_rms = np.sqrt(np.mean(np.sum((dst - truth.apply(src)) ** 2, axis=1)))
    assert result.rms <= true_rms + 1e-12


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS)
def test_a_reflected_target_gives_the_best_proper_rotation(seed):
    _, R, t, _, src = _draw(seed)
    mirror = np.diag([1.0, 1.0, -1.0])
    dst = src @ (R @ mirror).T + t  # mirrored: no rotation maps src onto dst
    result = umeyama(src, dst, with_scale=False)
    assert result.reflection_corrected
    assert np.linalg.det(result.transform.rotation) == pytest.approx(1.0)
    # no proper rotation does better (compare with random ones and with the unconstrained SVD's neighbours)
    rng = np.random.default_rng(seed)
    for _ in range(20):
        R_try = Rotation.random(random_state=rng.integers(2**31)).as_matrix()
        c_src, c_dst = src.mean(0), dst.mean(0)
        rms = np.sqrt(np.mean(np.sum((dst - ((src - c_src) @ R_try.T + c_dst)) ** 2, axis=1)))
        assert result.rms <= rms + 1e-12


def test_planar_points_and_two_dimensions():
    rng = np.random.default_rng(1)
    src = np.c_[rng.normal(size=(10, 2)), np.zeros(10)]  # coplanar, rank 2 = d - 1: still unique
    R = Rotation.from_rotvec([0.3, -0.2, 1.0]).as_matrix()
    result = umeyama(src, src @ R.T + 1.0, with_scale=False)
    np.testing.assert_allclose(result.transform.rotation, R, atol=1e-9)
    angle = 0.7
    R2 = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    pts = rng.normal(size=(6, 2))
    result = umeyama(pts, 2.0 * pts @ R2.T)
    np.testing.assert_allclose(result.transform.rotation, R2, atol=1e-9)
    assert result.transform.scale == pytest.approx(2.0)


def test_weights_and_nan_rows():
    rng = np.random.default_rng(2)
    src = rng.normal(size=(8, 3))
    R = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix()
    dst = src @ R.T
    dst_bad = dst.copy()
    dst_bad[0] += 5.0  # an outlier with zero weight is ignored
    result = umeyama(src, dst_bad, weights=[0.0] + [1.0] * 7, with_scale=False)
    np.testing.assert_allclose(result.transform.rotation, R, atol=1e-9)
    src_nan = src.copy()
    src_nan[3] = np.nan  # rows with NaN are ignored
    np.testing.assert_allclose(umeyama(src_nan, dst).transform.rotation, R, atol=1e-9)


@pytest.mark.parametrize(
    ("src", "dst", "reason"),
    [
        (np.zeros((2, 3)), np.zeros((2, 3)), "usable"),
        (np.ones((5, 3)), np.ones((5, 3)), "coincide"),
        (np.outer(np.arange(5.0), [1.0, 2.0, 3.0]), np.outer(np.arange(5.0), [3.0, 2.0, 1.0]), "degenerate"),
        (np.zeros((5, 3)), np.zeros((4, 3)), "expected"),
    ],
)
def test_degenerate_inputs_raise(src, dst, reason):
    with pytest.raises(AlignmentError, match=reason):
        umeyama(src, dst)


def test_transform_algebra():
    T = SimilarityTransform(Rotation.from_rotvec([0.1, 0.5, -0.3]).as_matrix(), np.array([1.0, 2.0, 3.0]), 1.7)
    p = np.array([[0.3, -0.2, 0.5], [1.0, 1.0, 1.0]])
    np.testing.assert_allclose(T.inverse().apply(T.apply(p)), p, atol=1e-12)
    np.testing.assert_allclose(T.compose(T.inverse()).apply(p), p, atol=1e-12)
    M = T.as_se3()
    np.testing.assert_allclose(M.rotation, T.rotation)
