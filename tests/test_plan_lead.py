"""Plan lead: the horizontal CoM and ZMP references taken ahead along the plan (position-controlled schemes)."""

import numpy as np
import pytest

from wbcbench.controllers.plan_lead import PlanLead, PlanLeadConfig
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.errors import ConfigError
from wbcbench.side import Side
from wbcbench.types import PointReference, References

DT = 0.001


def _plan(t):
    """A CoM under constant acceleration (0.3, -0.2, 0.1) m/s^2 and a ZMP moving at (0.5, -0.4) m/s."""
    a = np.array([0.3, -0.2, 0.1])
    com = PointReference(np.array([0.1, 0.0, 0.86]) + 0.5 * a * t * t, a * t, a)
    zmp = np.array([0.05 + 0.5 * t, 0.1 - 0.4 * t, 0.02])
    return References(t=t, contacts=frozenset(Side), com=com, zmp=zmp)


def test_the_com_and_the_horizontal_zmp_are_taken_ahead():
    lead = PlanLead(PlanLeadConfig(time=0.03), DT)
    first = lead.correct(_plan(1.0))
    np.testing.assert_array_equal(first.zmp, _plan(1.0).zmp)          # no rate yet: the ZMP as planned
    out = lead.correct(_plan(1.001))
    ahead, now = _plan(1.031), _plan(1.001)
    np.testing.assert_allclose(out.com.position, ahead.com.position, atol=1e-12)
    np.testing.assert_allclose(out.com.velocity, ahead.com.velocity, atol=1e-12)
    np.testing.assert_allclose(out.zmp, [*ahead.zmp[:2], now.zmp[2]], atol=1e-9)   # the ground's height as planned
    assert out.contacts == now.contacts and out.t == now.t


def test_a_gap_in_time_restarts_the_zmp_rate():
    lead = PlanLead(PlanLeadConfig(), DT)
    lead.correct(_plan(1.0))
    out = lead.correct(_plan(1.5))
    np.testing.assert_array_equal(out.zmp, _plan(1.5).zmp)
    lead.reset()
    np.testing.assert_array_equal(lead.correct(_plan(1.501)).zmp, _plan(1.501).zmp)


def test_taskset_key_and_its_errors(talos, tmp_path):
    assert load_taskset(taskset_path(talos, "tsid-position"), talos).plan_lead is None
    text = taskset_path(talos, "tsid-position").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text + "plan_lead: {time: 0.03}\n")
    assert load_taskset(bad, talos).plan_lead == PlanLeadConfig(time=0.03)
    for entry, needle in (("{time: [0.02]}", "time"), ("{time: 0.0}", "time"), ("{time: -0.01}", "time"),
                          ("{time: 0.02, tme: 1}", "tme")):
        bad.write_text(text + f"plan_lead: {entry}\n")
        with pytest.raises(ConfigError, match=needle) as err:
            load_taskset(bad, talos)
        assert "bad.yaml" in str(err.value) and "\n" not in str(err.value)
