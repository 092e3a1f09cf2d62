"""The compiled sole-wrench kernel gives what MuJoCo's own `mj_contactForce` gives, contact by contact, with the
pyramidal (default) and the elliptic friction cone, TALOS standing (tsid-torque) and while a sideways push loads the feet unevenly
and makes them slide-stick (tangential forces)."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.controllers.base import make_controller
from wbcbench.robots import Side
from wbcbench.sim.push import Push
from wbcbench.sim.simulator import Simulator
from wbcbench.types import PointReference, References


def reference_wrenches(sim):
    """The ground-truth sole wrenches from `mj_contactForce`, one contact per call (world axes, moment about
    the world origin)."""
    d = sim.data
    out = {s: np.zeros(6) for s in Side}
    cf = np.zeros(6)
    for i in range(d.ncon):
        con = d.contact[i]
        mujoco.mj_contactForce(sim.model, d, i, cf)
        f = con.frame.reshape(3, 3).T @ cf[:3]  # contact frame rows are its axes
        for s, gid in sim._sole_geoms.items():
            sign = -1.0 if con.geom1 == gid else 1.0 if con.geom2 == gid else 0.0
            if sign:
                out[s][:3] += sign * f
                out[s][3:] += np.cross(con.pos, sign * f)
    return out


@pytest.mark.parametrize("cone", ["pyramidal", "elliptic"])
def test_sole_wrenches_match_mj_contact_force(talos, cone):
    ctrl = make_controller("tsid-torque", talos, None, 1e-3)
    sim = Simulator(talos, mode=ctrl.mode, pushes=(Push("base", (0.0, 150.0, 0.0), 0.1, 0.2),))
    if cone == "elliptic":
        sim.model.opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        sim._pyramidal = False
    meas = sim.measure()
    com = pin.centerOfMass(talos.model, talos.model.createData(), meas.q).copy()
    refs = References(t=0.0, com=PointReference(com), zmp=np.array([com[0], com[1], 0.0]))
    ctrl.reset(meas, refs)
    tangential, uneven = 0.0, 0.0
    for k in range(400):
        sim.apply(ctrl.step(meas, refs))
        sim.step()
        meas = sim.measure()
        if k % 20 == 19 and k > 100:  # after the drop onto the floor
            got, ref = sim.contact_wrenches(), reference_wrenches(sim)
            for s in Side:
                np.testing.assert_allclose(got[s], ref[s], rtol=1e-12, atol=1e-9)
            tangential = max(tangential, *(abs(ref[s][1]) for s in Side))
            uneven = max(uneven, abs(ref[Side.LEFT][2] - ref[Side.RIGHT][2]))
            assert ref[Side.LEFT][2] + ref[Side.RIGHT][2] > 0.5 * talos.mass * 9.81  # real, loaded contacts
    assert tangential > 5.0 and uneven > 20.0  # the push made the comparison cover friction and load transfer
