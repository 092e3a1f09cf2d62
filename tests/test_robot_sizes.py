"""Scenario sizes per robot: a profile's `scenarios:` entry replaces keys of a scenario run on that robot, and
`reproduce --robot` writes the paper's report for another robot with our numbers only."""

import json
from pathlib import Path

import pytest
import yaml

from wbcbench import load_robot
from wbcbench.errors import ConfigError
from wbcbench.report import matrix, report, reproduce
from wbcbench.robots.profile import PROFILE_DIR
from wbcbench.scenarios.base import load_scenario


def _g1_profile(tmp_path: Path, **extra) -> Path:
    data = yaml.safe_load((PROFILE_DIR / "g1.yaml").read_text())
    data.update(extra)
    p = tmp_path / "g1.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


def test_a_profile_sizes_a_scenario_for_its_robot(tmp_path):
    robot = load_robot(_g1_profile(tmp_path, scenarios={
        "walk-20cm": {"params": {"step_length": 0.15}},
        "stairs-quick": {"terrain": {"height": 0.07}, "params": {"swing_clearance": 0.04}}}))
    walk = load_scenario("walk-20cm", robot)
    assert walk.step_length == pytest.approx(0.15) and walk.n_steps == 6      # the file's other keys kept
    assert "Sized for g1 by its profile: params step_length: 0.15." in walk.spec.description
    stairs = load_scenario("stairs-quick", robot)
    assert stairs.spec.terrain.boxes[0].size[2] == pytest.approx(0.07)        # first riser 7 cm high
    assert stairs.clearance == pytest.approx(0.04) and stairs.goal.tolist() == [0.75, 0.0]
    # a scenario the profile does not size, and another robot: the file as it is
    assert load_scenario("walk-20cm-quick", robot).step_length == pytest.approx(0.20)
    assert load_scenario("walk-20cm", load_robot("talos")).step_length == pytest.approx(0.20)


def test_bad_scenario_sizes_are_one_config_error(tmp_path):
    with pytest.raises(ConfigError, match=r"scenarios\.walk-20cm.*allowed here: params, terrain"):
        load_robot(_g1_profile(tmp_path, scenarios={"walk-20cm": {"step_length": 0.15}}))
    robot = load_robot(_g1_profile(tmp_path, scenarios={"walk-20cm": {"params": {"step_length": "long"}}}))
    # the error names the scenario file and the profile that gave the value
    with pytest.raises(ConfigError, match=r"walk-20cm.yaml \(with the sizes of .*g1.yaml\): "
                                          r"key .params\.step_length.: must be a number"):
        load_scenario("walk-20cm", robot)


def test_reproduce_for_another_robot_has_our_numbers_only(monkeypatch, tmp_path):
    """`reproduce --robot g1` on a tiny matrix: the cells run on the G1, every published value is n/a, and the
    report says which robot and which sizes its profile gives."""
    monkeypatch.setattr(matrix, "PAPER_MATRIX", (("tsid-torque", "walk-20cm"),))
    monkeypatch.setattr(matrix, "FAST_MATRIX", (("tsid-torque", "walk-20cm-fast"),))
    # no -quick variants: the walks are cut at the cap
    monkeypatch.setattr(matrix, "available_scenarios", lambda: ["walk-20cm", "walk-20cm-fast"])
    monkeypatch.setattr(matrix, "QUICK_WALK_CAP_S", 0.3)
    res = reproduce(tmp_path, quick=True, jobs=1, progress=False, sanity=False, keyframes=False, robot="g1")
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["command"] == "reproduce --quick --robot g1 --no-keyframes"
    assert results["robot"]["name"] == "g1"
    assert results["robot"]["scenario_sizes"] == load_robot("g1").profile.scenario_overrides
    cell = results["tables"]["table2"]["values"]["tsid-torque"]["walk-20cm"]
    assert cell["status"] == "ok" and cell["zmp_error_m.x.mean"]["paper"] is None
    assert isinstance(cell["zmp_error_m.x.mean"]["ours"], float)
    assert all(not t["paper_reference_rows"] for t in results["tables"].values())
    assert results["fast_walk"]["values"]["tsid-torque"]["paper"] == "n/a"
    config = json.loads((Path(res.outcomes[0].run_dir) / "config.json").read_text())
    assert config["robot"] == "g1"
    md = (tmp_path / "report.md").read_text()
    assert "Robot: g1" in md and "every 'paper' column is n/a" in md
    # the same from the run directories alone
    again = report([o.run_dir for o in res.outcomes], tmp_path / "again")
    assert again.results["robot"]["name"] == "g1"
    assert again.results["tables"]["table2"]["values"]["tsid-torque"]["walk-20cm"]["zmp_error_m.x.mean"] == \
        cell["zmp_error_m.x.mean"]


@pytest.mark.parametrize("robot_name", ["talos", "g1"])
def test_no_shipped_scenario_plans_the_com_above_the_robots_standing_height(robot_name):
    """A scenario's `com_height` is TALOS-sized unless the robot's profile sizes it: every shipped scenario, as
    loaded for each shipped robot, plans the CoM below that robot's standing CoM height above its soles (the
    platforms' 0.86 m, TALOS' walking height, once reached the G1 unsized: its position schemes fell)."""
    import pinocchio as pin

    from wbcbench.scenarios import available_scenarios
    from wbcbench.side import Side

    robot = load_robot(robot_name)
    m, d = robot.model, robot.model.createData()
    pin.framesForwardKinematics(m, d, robot.q0)
    standing = pin.centerOfMass(m, d, robot.q0)[2] - min(d.oMf[robot.sole_frame_id(s)].translation[2] for s in Side)
    for name in available_scenarios():
        height = getattr(load_scenario(name, robot), "com_height", None)
        assert height is None or height < standing, (name, height, standing)
