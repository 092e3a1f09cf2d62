"""Touch-down search: a foot unloaded at its planned touch-down keeps descending as a swing foot until loaded."""

import numpy as np
import pytest

from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.controllers.touchdown import TouchdownSearch, TouchdownSearchConfig
from wbcbench.errors import ConfigError
from wbcbench.side import Side
from wbcbench.types import Measurement, PoseReference, References

L, R = Side.LEFT, Side.RIGHT
SLOPE = np.array([[np.cos(0.26), 0.0, np.sin(0.26)], [0.0, 1.0, 0.0], [-np.sin(0.26), 0.0, np.cos(0.26)]])


def _meas(t, load_left, load_right=800.0):
    """A measurement whose ankle sensors read these normal loads [N] (sensor z force = -load)."""
    return Measurement(t=t, q=np.zeros(7), v=np.zeros(6), imu_quat=np.array([0, 0, 0, 1.0]), gyro=np.zeros(3),
                       accelerometer=np.zeros(3), ft_force={L: np.array([0, 0, -load_left]),
                                                            R: np.array([0, 0, -load_right])})


def _swing(t):
    return References(t=t, contacts=frozenset({R}), feet={L: PoseReference([0.3, 0.1, 0.04], SLOPE)})


def _landed(t):
    return References(t=t, contacts=frozenset(Side))


def test_an_unloaded_foot_descends_along_its_sole_normal_until_loaded():
    search = TouchdownSearch(TouchdownSearchConfig(speed=0.1, max_depth=0.02, min_force=100.0))
    out = search.correct(_meas(0.0, -16.0), _swing(0.0))
    assert out.contacts == {R}
    # planned touch-down, the foot unloaded: no contact yet, its last swing reference moves down the sole normal
    out = search.correct(_meas(0.001, -16.0), _landed(0.001))
    assert out.contacts == {R} and search.searching == {L}
    out = search.correct(_meas(0.031, 40.0), _landed(0.031))
    assert out.contacts == {R}
    foot = out.feet[L]
    assert foot.position == pytest.approx(np.array([0.3, 0.1, 0.04]) - 0.003 * SLOPE[:, 2])
    assert foot.velocity[:3] == pytest.approx(-0.1 * SLOPE[:, 2])
    np.testing.assert_array_equal(foot.rotation, SLOPE)
    # loaded: the contact is made (where the model's foot is), and kept
    for t in (0.032, 0.033):
        out = search.correct(_meas(t, 150.0), _landed(t))
        assert out.contacts == frozenset(Side) and not search.searching
    assert search.n_searches == 1


@pytest.mark.parametrize("why", ["depth", "other_foot_leaves"])
def test_the_search_ends_at_its_depth_or_when_the_other_foot_leaves(why):
    search = TouchdownSearch(TouchdownSearchConfig(speed=0.1, max_depth=0.02, min_force=100.0))
    search.correct(_meas(0.0, 0.0), _swing(0.0))
    assert search.correct(_meas(0.001, 0.0), _landed(0.001)).contacts == {R}
    if why == "depth":       # 2 cm at 0.1 m/s: 0.2 s after the planned touch-down
        assert search.correct(_meas(0.15, 0.0), _landed(0.15)).contacts == {R}
        assert search.correct(_meas(0.202, 0.0), _landed(0.202)).contacts == frozenset(Side)
    else:                    # the right foot's lift-off is planned: the left contact is made now
        out = search.correct(_meas(0.05, 0.0), References(t=0.05, contacts=frozenset({L})))
        assert out.contacts == {L}
    assert not search.searching


def test_a_loaded_or_standing_foot_is_not_searched():
    search = TouchdownSearch(TouchdownSearchConfig())
    refs = _landed(0.0)
    assert search.correct(_meas(0.0, 0.0), refs) is refs        # both feet down from the start: nothing to search
    search.correct(_meas(0.1, 0.0), _swing(0.1))
    refs = _landed(0.2)
    assert search.correct(_meas(0.2, 300.0), refs) is refs      # touched down early: loaded at the planned time
    assert search.n_searches == 0


def test_taskset_key_and_its_errors(talos, tmp_path):
    spec = load_taskset(taskset_path(talos, "tsid-position"), talos)
    assert spec.touchdown_search == TouchdownSearchConfig(speed=0.1, max_depth=0.02, min_force=100.0)
    assert load_taskset(taskset_path(talos, "tsid-torque"), talos).touchdown_search is None
    text = taskset_path(talos, "tsid-position").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("touchdown_search: {speed: 0.1,", "touchdown_search: {speed: -0.1,"))
    with pytest.raises(ConfigError, match="speed") as err:
        load_taskset(bad, talos)
    assert "bad.yaml" in str(err.value)
    bad.write_text(text.replace("touchdown_search: {speed: 0.1,", "touchdown_search: {sped: 0.1,"))
    with pytest.raises(ConfigError, match="sped"):
        load_taskset(bad, talos)
