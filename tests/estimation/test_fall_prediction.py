"""Fall prediction: capture point against the support polygon, from the measurement."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from wbcbench.estimation.fall import convex_hull, signed_distance_to_polygon
from wbcbench.runner import run
from wbcbench.scenarios import load_scenario
from wbcbench.sim.push import Push


def test_hull_and_signed_distance():
    rng = np.random.default_rng(0)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [0.2, 0.7]], float)
    hull = convex_hull(np.vstack([square, rng.uniform(0, 1, (20, 2))]))
    assert len(hull) == 4
    assert signed_distance_to_polygon(np.array([0.5, 0.5]), hull) == pytest.approx(0.5)
    assert signed_distance_to_polygon(np.array([0.5, 0.9]), hull) == pytest.approx(0.1)
    assert signed_distance_to_polygon(np.array([1.3, 0.5]), hull) == pytest.approx(-0.3)
    assert signed_distance_to_polygon(np.array([1.3, 1.4]), hull) == pytest.approx(-0.5)


@pytest.mark.parametrize("impulse,falls", [(20.0, False), (60.0, True)])
def test_prediction_comes_before_the_fall(talos, tmp_path, impulse, falls):
    """tsid-torque standing, pushed sideways for 0.1 s: 20 N s is survived with no alarm; 60 N s is predicted
    within 0.15 s of the push and the robot falls later (measured: 0.8 s later)."""
    scen = load_scenario("stand", talos, 2.5)
    scen.spec = replace(scen.spec, pushes=(Push("base", (0.0, impulse / 0.1, 0.0), 1.0, 0.1),))
    res = run(scen, "tsid-torque", robot=talos, out=tmp_path / "r", predict_falls=True)
    fp = res.summary["fall_prediction"]
    assert res.summary["fell"] is falls
    if falls:
        assert 1.0 <= fp["first_prediction_t"] < 1.15 and fp["time_to_fall_s"] > 0.2
        assert res.log["fall_prediction.cp_margin"].min() < -0.05
    else:
        assert fp["first_prediction_t"] is None and not fp["false_alarm"]
        assert res.log["fall_prediction.cp_margin"].min() > 0.0
