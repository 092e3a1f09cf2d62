"""The one place where the pinocchio computations needed by the tasks are run, once per control tick.

Two entry points:

* :func:`update_kinematics` (acceleration level, inverse dynamics): one call to ``pin.computeAllTerms``.
  In pinocchio 4.1 (``src/algorithm/compute-all-terms.hxx``, checked against the separate algorithms in
  ``tests/tasks/test_kinematics.py``) that single pass fills everything the tasks and an inverse-dynamics
  QP need:

  ============================  ==================================================================
  field                         content
  ============================  ==================================================================
  ``data.M``, ``data.nle``      joint-space inertia (symmetric from Python) and ``C(q, v) v + g(q)``
  ``data.g``                    gravity torques
  ``data.oMi``, ``data.liMi``   joint placements (frames are derived on demand from ``oMi``)
  ``data.J``, ``data.dJ``       joint Jacobians in WORLD and their time variation
  ``data.v``, ``data.ov``       joint spatial velocities (local, world)
  ``data.a``                    joint spatial accelerations *with zero joint acceleration*: exactly the
                                ``data.a`` of ``forwardKinematics(q, v, 0)``, so ``getFrameAcceleration``
                                and ``getFrameClassicalAcceleration`` return the drift ``J_dot v``
  ``data.com[0]``, ``vcom[0]``  centre of mass position and velocity (``data.acom`` is NOT filled)
  ``data.Jcom``, ``data.Ag``    CoM Jacobian and centroidal momentum matrix
  ``data.dAg``                  time variation of ``Ag``: ``dAg v`` is the centroidal momentum drift
                                (``computeCentroidalMapTimeVariation`` is not needed); the CoM drift is
                                ``dAg[:3] v / m``
  ``data.hg``                   centroidal momentum ``Ag v``
  ============================  ==================================================================

  So ``forwardKinematics(q, v, 0)``, ``centerOfMass(q, v, 0)`` and ``computeCentroidalMapTimeVariation``
  would only repeat work. Frame placements (``data.oMf``) are NOT updated here: each task refreshes only its
  own frame with ``pin.updateFramePlacement`` (updating all 121 TALOS frames would be wasted work).

* :func:`update_kinematics_velocity_level` (velocity level, IK): one call to ``pin.computeCentroidalMap``,
  which runs forward kinematics and fills ``data.oMi``, ``data.J``, ``data.Ag`` and ``data.com[0]``: all an
  IK needs for frame, CoM, posture and angular-momentum rows. Velocities, drifts and dynamics are left stale.

Both store their inputs in pinocchio's own input fields ``data.q_in`` (nq) and ``data.v_in`` (nv), which is how
tasks that need ``q`` or ``v`` themselves (posture error, CoM and momentum drifts) read them; tasks therefore
depend on ``(model, data)`` only. Call one of these functions before evaluating any task in a tick.

Measured on the development machine (TALOS, nq 39, nv 38; see the task-library report): about 19 us for
:func:`update_kinematics` and 4 us for :func:`update_kinematics_velocity_level`.
"""

from __future__ import annotations

import numpy.typing as npt
import pinocchio as pin

__all__ = ["update_kinematics", "update_kinematics_velocity_level"]


def update_kinematics(model: pin.Model, data: pin.Data, q: npt.ArrayLike, v: npt.ArrayLike) -> None:
    """Run every pinocchio computation the tasks need at acceleration level (and M, nle for the dynamics).

    Args:
        model: the robot model.
        data: its data, updated in place.
        q: configuration, shape (nq,) (free-flyer: position [m] then quaternion x, y, z, w).
        v: generalized velocity, shape (nv,) (free-flyer: linear then angular velocity in the LOCAL base
            frame, m/s and rad/s).

    Raises:
        ValueError: ``q`` or ``v`` has the wrong size (from pinocchio).
    """
    pin.computeAllTerms(model, data, q, v)
    data.q_in = q
    data.v_in = v


def update_kinematics_velocity_level(model: pin.Model, data: pin.Data, q: npt.ArrayLike) -> None:
    """Run the pinocchio computations the tasks need at velocity level (IK): placements, Jacobians, CoM, Ag.

    After this call, ``jacobian`` and ``error`` of every task are valid, ``velocity`` and ``drift`` are not.

    Args:
        model: the robot model.
        data: its data, updated in place.
        q: configuration, shape (nq,).

    Raises:
        ValueError: ``q`` has the wrong size (from pinocchio).
    """
    pin.computeCentroidalMap(model, data, q)
    data.q_in = q
