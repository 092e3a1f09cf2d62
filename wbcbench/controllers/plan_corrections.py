"""The corrections a controller makes to the plan's references before its solve, in their order:

1. the plan lead (`plan_lead.PlanLead`, task-set key `plan_lead`): the CoM and the horizontal ZMP references taken
   a little ahead along the plan, for a robot that lags its integrated model;
2. the event-based lift-off (`liftoff.LiftOffWait`, task-set key `lift_off_wait`): a foot still loaded at its
   planned lift-off stays in contact until its F/T sensor reads it unloaded (bounded), then its swing catches up
   with the plan;
3. the touch-down search (`touchdown.TouchdownSearch`, task-set key `touchdown_search`): a foot unloaded at its
   planned touch-down keeps descending until its F/T sensor reads a load;
4. the base feedback (`wbcbench.estimation.base_feedback.BaseFeedback`, task-set key `base_feedback`): the plan
   mapped into the integrated model's world, so that a position-controlled scheme does not drift from it;
5. the swing-foot tilt compensation (`swing_tilt.SwingTilt`, task-set key `swing_tilt`): a swing foot turned against
   the tilt the stance leg's yielding joints give the real one, so that it lands flatter;
6. the stabilizer (any `wbcbench.stabilizers` type, task-set key `stabilizer`), given what it may know of the model.

The first five exist only for a controller that integrates its own model (`integrated_model`: IK, the
inverse-dynamics controllers in position and SPD modes); in torque mode the contact forces press a foot down and
the model is the measured state. Each is built from the task set when it has the section, and is absent otherwise.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..estimation.base_feedback import BaseFeedback
from ..robots import Robot
from ..stabilizers.base import Stabilizer, make_stabilizer
from ..types import Measurement, ModelFeedback, References
from .liftoff import LiftOffWait
from .plan_lead import PlanLead
from .swing_tilt import SwingTilt
from .taskset import TaskSetSpec
from .touchdown import TouchdownSearch

__all__ = ["PlanCorrections"]


class PlanCorrections:
    """The plan lead, lift-off wait, touch-down search, base feedback and stabilizer of a controller (module
    docstring).

    Args:
        robot, dt: the controller's.
        spec: its task set (sections `plan_lead`, `lift_off_wait`, `touchdown_search`, `base_feedback`, `stabilizer`).
        stabilizer: a stabilizer to use instead of the task set's (None: the task set's, if any).
        integrated_model: whether the controller integrates its own model (the plan lead, the lift-off wait,
            the touch-down search and the base feedback are built only then).
    """

    def __init__(self, robot: Robot, dt: float, spec: TaskSetSpec, stabilizer: Stabilizer | None = None,
                 integrated_model: bool = True):
        if stabilizer is None and spec.stabilizer is not None:
            stabilizer = make_stabilizer(spec.stabilizer, robot, dt)
        self.stabilizer = stabilizer
        self.lead = PlanLead(spec.plan_lead, dt) if spec.plan_lead is not None and integrated_model else None
        self.lift_off = (LiftOffWait(spec.lift_off_wait)
                         if spec.lift_off_wait is not None and integrated_model else None)
        self.touchdown = (TouchdownSearch(spec.touchdown_search)
                          if spec.touchdown_search is not None and integrated_model else None)
        self.base_feedback = (BaseFeedback(robot, dt, spec.base_feedback)
                              if spec.base_feedback is not None and integrated_model else None)
        self.swing_tilt = (SwingTilt(spec.swing_tilt, robot, dt)
                           if spec.swing_tilt is not None and integrated_model else None)

    def reset(self, meas: Measurement, refs: References, feedback: Callable[[], ModelFeedback]) -> None:
        """At the controller's reset; `feedback()` is the stabilizer's model feedback at reset (called only when
        there is a stabilizer). Raises the stabilizer's `MissingReferenceError` when the references lack one it
        needs."""
        if self.lead is not None:
            self.lead.reset()
        if self.lift_off is not None:
            self.lift_off.reset()
        if self.touchdown is not None:
            self.touchdown.reset()
        if self.base_feedback is not None:
            self.base_feedback.reset()
        if self.swing_tilt is not None:
            self.swing_tilt.reset()
        if self.stabilizer is not None:
            self.stabilizer.check(refs)
            self.stabilizer.reset(meas, refs, feedback())

    def apply(self, meas: Measurement, refs: References, q_model: np.ndarray | None,
              feedback: Callable[[References], ModelFeedback]) -> References:
        """This tick's references with the corrections applied in order. `q_model`: the integrated model's
        configuration (for the base feedback); `feedback(refs)`: the stabilizer's model feedback for the references
        corrected so far (called only when there is a stabilizer)."""
        if self.lead is not None:
            refs = self.lead.apply(refs)
        if self.lift_off is not None:
            refs = self.lift_off.apply(meas, refs)
        if self.touchdown is not None:
            refs = self.touchdown.apply(meas, refs)
        if self.base_feedback is not None:
            refs = self.base_feedback.correct(meas, refs, q_model)
        if self.swing_tilt is not None:
            refs = self.swing_tilt.apply(meas, refs, q_model)
        if self.stabilizer is not None:
            refs = self.stabilizer.correct(meas, refs, feedback(refs))
        return refs

    def status(self, out: dict) -> dict:
        """`out` with the corrections' counters added (the lift-offs delayed and their summed delay [s], the
        touch-down searches made)."""
        if self.lift_off is not None:
            out["lift_off_waits"] = self.lift_off.n_waits
            out["lift_off_wait_s"] = round(self.lift_off.total_wait, 4)
        if self.touchdown is not None:
            out["touchdown_searches"] = self.touchdown.n_searches
        if self.swing_tilt is not None:
            out["swing_tilt_max_rad"] = round(self.swing_tilt.max_tilt, 5)
        return out
