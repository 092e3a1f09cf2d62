"""Per-axis tracking error statistics."""

import numpy as np
import pytest

from wbcbench.metrics import tracking_error_stats


def test_constant_offset():
    ref = np.zeros((50, 2))
    meas = ref + [0.01, -0.02]
    stats = tracking_error_stats(ref, meas)
    assert set(stats) == {"x", "y"}
    assert stats["x"] == pytest.approx({"mean": 0.01, "std": 0.0, "peak": 0.01, "rms": 0.01}, abs=1e-15)
    assert stats["y"] == pytest.approx({"mean": 0.02, "std": 0.0, "peak": 0.02, "rms": 0.02}, abs=1e-15)


def test_sinusoid_over_whole_periods():
    a, n = 0.03, 100_000
    t = np.arange(n) * (4 * np.pi / n)  # two periods
    ref = np.zeros((n, 3))
    meas = np.stack([a * np.sin(t), 0.01 + a * np.sin(t), np.zeros(n)], axis=1)
    stats = tracking_error_stats(ref, meas)
    assert stats["x"]["mean"] == pytest.approx(2 * a / np.pi, rel=1e-6)
    assert stats["x"]["std"] == pytest.approx(a / np.sqrt(2), rel=1e-6)  # std of the signed error
    assert stats["x"]["peak"] == pytest.approx(a, rel=1e-6)
    assert stats["x"]["rms"] == pytest.approx(a / np.sqrt(2), rel=1e-6)
    assert stats["y"]["std"] == pytest.approx(a / np.sqrt(2), rel=1e-6)  # offset does not change std
    assert stats["y"]["peak"] == pytest.approx(0.01 + a, rel=1e-6)
    assert stats["z"] == {"mean": 0.0, "std": 0.0, "peak": 0.0, "rms": 0.0}


def test_one_dimensional_and_named_axes():
    assert tracking_error_stats([0.0, 0.0], [1.0, -1.0])["x"]["mean"] == 1.0
    stats = tracking_error_stats(np.zeros((3, 4)), np.ones((3, 4)), axes=["x", "y", "z", "yaw"])
    assert list(stats) == ["x", "y", "z", "yaw"]


def test_mask_excludes_ticks_and_their_nans():
    ref = np.zeros((4, 2))
    meas = np.array([[0.1, 0.1], [np.nan, np.nan], [0.3, -0.1], [5.0, 5.0]])
    stats = tracking_error_stats(ref, meas, mask=[True, False, True, False])
    assert stats["x"]["mean"] == pytest.approx(0.2)
    assert stats["x"]["peak"] == pytest.approx(0.3)
    assert stats["y"]["std"] == pytest.approx(0.1)


@pytest.mark.parametrize(
    ("ref", "meas", "kwargs", "match"),
    [
        (np.zeros((5, 2)), np.zeros((4, 2)), {}, "mismatched lengths"),
        (np.zeros((5, 2)), np.zeros((5, 3)), {}, "shape"),
        (np.zeros((0, 2)), np.zeros((0, 2)), {}, "empty"),
        (np.zeros((2, 2)), np.array([[0.0, np.nan], [0.0, 0.0]]), {}, "non-finite"),
        (np.zeros((2, 2)), np.array([[0.0, np.inf], [0.0, 0.0]]), {"mask": [True, False]}, "non-finite"),
        (np.zeros((2, 2)), np.zeros((2, 2)), {"mask": [False, False]}, "no tick"),
        (np.zeros((2, 2)), np.zeros((2, 2)), {"mask": [True]}, "mismatched lengths"),
        (np.zeros((2, 4)), np.zeros((2, 4)), {}, "axes"),
        (np.zeros((2, 2)), np.zeros((2, 2)), {"axes": ["x"]}, "axes"),
        (np.zeros((2, 2, 2)), np.zeros((2, 2, 2)), {}, "shape"),
    ],
)
def test_bad_input_raises(ref, meas, kwargs, match):
    with pytest.raises(ValueError, match=match):
        tracking_error_stats(ref, meas, **kwargs)
