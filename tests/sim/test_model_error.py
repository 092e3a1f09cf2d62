"""Model error: the simulated robot differs from the controller's model exactly as specified."""

from __future__ import annotations

import subprocess
import sys

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.runner import run
from wbcbench.sim.model_error import ModelError, Payload
from wbcbench.sim.simulator import Simulator


def test_payload_moves_the_mass_and_the_com_exactly(talos):
    offset = np.array([-0.2, 0.05, 0.1])
    sim = Simulator(talos, model_error=ModelError(payloads=(Payload("torso_2_link", 8.0, tuple(offset)),)))
    nominal = Simulator(talos)
    m, d = talos.model, talos.model.createData()
    pin.framesForwardKinematics(m, d, talos.q0)
    p_payload = d.oMf[m.getFrameId("torso_2_link")].act(offset)
    com = pin.centerOfMass(m, d, talos.q0)
    expected = (talos.mass * com + 8.0 * p_payload) / (talos.mass + 8.0)
    mujoco.mj_forward(sim.model, sim.data)
    np.testing.assert_allclose(sim.data.subtree_com[1], expected, atol=1e-9)
    assert sim.model.body_mass[1:].sum() == pytest.approx(nominal.model.body_mass[1:].sum() + 8.0)


def test_mass_error_is_bounded_and_seeded(talos):
    a = Simulator(talos, model_error=ModelError(mass_error=0.1, seed=4))
    b = Simulator(talos, model_error=ModelError(mass_error=0.1, seed=4))
    n = Simulator(talos)
    ratio = a.model.body_mass[1:] / n.model.body_mass[1:]
    assert np.all(np.abs(ratio - 1) <= 0.1 + 1e-12) and np.abs(ratio - 1).max() > 0.05
    np.testing.assert_array_equal(a.model.body_mass, b.model.body_mass)
    c = Simulator(talos, model_error=ModelError(friction=0.35, ground_timeconst=0.05))
    assert np.all(c.model.geom_friction[:, 0] == 0.35)
    floor = mujoco.mj_name2id(c.model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    assert c.model.geom_solref[floor, 0] == 0.05


def test_an_unmodelled_payload_is_felt_by_the_controller(tmp_path):
    """tsid-torque standing with 15 kg it does not know of on its torso: it still stands, but sinks (its torques
    are for the nominal mass); without model error it keeps its height to a millimetre."""
    me = ModelError(payloads=(Payload("torso_2_link", 15.0, (-0.1, 0.0, 0.1)),))
    a = run("stand", "tsid-torque", duration=1.5, out=tmp_path / "a", model_error=me)
    b = run("stand", "tsid-torque", duration=1.5, out=tmp_path / "b")
    assert not a.summary["fell"] and not b.summary["fell"]
    assert a.summary["metrics"]["base_height_change_m"] < -0.01
    assert abs(b.summary["metrics"]["base_height_change_m"]) < 0.002


def test_bad_model_error_files(tmp_path):
    p = tmp_path / "me.yaml"
    for text, needle in (("payloads: [{link: torso_9_link, mass: 3}]\n", "torso_9_link"),
                         ("mass_error: 2.0\n", "mass_error"), ("payloads: [{link: torso_2_link, mass: -1}]\n", "mass")):
        p.write_text(text)
        out = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", "joint-pd", "--duration",
                              "0.01", "--model-error", str(p), "--out", str(tmp_path / "r")], capture_output=True,
                             text=True)
        assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and needle in out.stderr, out.stderr
