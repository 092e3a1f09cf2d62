"""Cross-check of the F/T sign convention against MuJoCo itself: a shin + foot resting on the floor.

The foot is yawed and its CoM is offset from the sensor site; the wrench recovered from the force/torque
sensors must equal the sum of the contact forces `mj_contactForce` reports.
"""

import numpy as np
import pytest

from wbcbench.estimation import FootMass, contact_wrench_from_ft

mujoco = pytest.importorskip("mujoco")

XML = """
<mujoco>
  <option timestep="0.001" integrator="implicitfast"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="shin" pos="0 0 0.45">
      <freejoint/>
      <geom type="box" size="0.03 0.03 0.15" pos="0.02 0.01 0.0" mass="5"/>
      <body name="foot" pos="0 0 -0.3" euler="0 0 0.4">
        <geom name="sole" type="box" size="0.1 0.065 0.01" pos="-0.02 0.0 -0.09" mass="1.6"/>
        <site name="ft" pos="0 0 0" euler="0.1 0 0.3"/>
      </body>
    </body>
  </worldbody>
  <sensor><force site="ft"/><torque site="ft"/></sensor>
</mujoco>
"""


def test_ft_conversion_matches_mujoco_contact_forces():
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    for _ in range(2000):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    assert np.abs(d.qvel).max() < 1e-5  # at rest

    foot_id, site_id = m.body("foot").id, m.site("ft").id
    R = d.site_xmat[site_id].reshape(3, 3).copy()
    p_site = d.site_xpos[site_id].copy()
    foot = FootMass(float(m.body_mass[foot_id]), R.T @ (d.xipos[foot_id] - p_site))
    w = contact_wrench_from_ft(d.sensordata[0:3], d.sensordata[3:6], R, p_site, foot,
                               gravity=m.opt.gravity.copy())

    force, moment = np.zeros(3), np.zeros(3)
    for i in range(d.ncon):
        c = d.contact[i]
        f6 = np.zeros(6)
        mujoco.mj_contactForce(m, d, i, f6)
        f_world = c.frame.reshape(3, 3).T @ f6[:3]
        if m.geom_bodyid[c.geom1] == foot_id:  # force of geom1 on geom2: flip when the foot is geom1
            f_world = -f_world
        force += f_world
        moment += np.cross(c.pos - p_site, f_world)

    np.testing.assert_allclose(force[2], m.body_subtreemass[1] * 9.81, rtol=1e-6)
    np.testing.assert_allclose(w.force, force, atol=1e-5)
    np.testing.assert_allclose(w.moment, moment, atol=1e-5)
    assert np.linalg.norm(moment[:2]) > 0.1  # the CoM offset makes a real moment to get right
