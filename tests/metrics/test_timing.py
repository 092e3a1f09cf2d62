"""Compute-time statistics."""

import numpy as np
import pytest

from wbcbench.metrics import timing_stats


def test_known_durations():
    s = timing_stats(np.arange(1, 101) * 1e-6)  # 1..100 us
    assert s.mean == pytest.approx(50.5)
    assert s.median == pytest.approx(50.5)
    assert s.p99 == pytest.approx(99.01)
    assert s.max == pytest.approx(100.0)
    assert s.n_ticks == 100


def test_single_tick():
    s = timing_stats([2.5e-4])
    assert s.mean == s.median == s.p99 == s.max == pytest.approx(250.0)


@pytest.mark.parametrize(
    ("durations", "match"),
    [
        ([], "empty"),
        ([1e-4, np.nan], "non-finite"),
        ([1e-4, -1e-6], "negative"),
        (np.zeros((3, 2)), "shape"),
    ],
)
def test_bad_input_raises(durations, match):
    with pytest.raises(ValueError, match=match):
        timing_stats(durations)
