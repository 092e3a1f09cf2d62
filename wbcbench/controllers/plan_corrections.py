"""A controller's plan corrections: its task set's correction stages (corrections.py), built once and run in order
each tick by one loop.

The stages come from the task set's `corrections:` list, or from its sections `plan_lead`, `lift_off_wait`,
`touchdown_search`, `base_feedback`, `swing_tilt`, `stabilizer` in that order (`TaskSetSpec.correction_specs`).
A stage that needs an integrated model (`Correction.needs_integrated_model`: the five built-ins before the
stabilizer) is left out of a controller without one (the inverse-dynamics controllers in torque mode, whose model is
the measured state, and whose contact forces press a landing foot down). A stabilizer given to the controller
replaces the task set's stabilizer stage, or comes last when the task set has none.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..robots import Robot
from ..stabilizers.base import Stabilizer
from ..types import Command, Measurement, ModelFeedback, References
from .corrections import Correction, CorrectionContext, StabilizerStage, correction_class
from .taskset import TaskSetSpec

__all__ = ["PlanCorrections"]


class PlanCorrections:
    """The correction stages of a controller, run in order (module docstring).

    Args:
        robot, dt: the controller's.
        spec: its task set (its `corrections:` list or its sections).
        stabilizer: a stabilizer to use instead of the task set's (None: the task set's, if any).
        integrated_model: whether the controller integrates its own model (stages that need one are built only
            then).

    Attributes:
        stages: the stages, in order (a tuple); `names`, `types`: their names and types.
    """

    def __init__(self, robot: Robot, dt: float, spec: TaskSetSpec, stabilizer: Stabilizer | None = None,
                 integrated_model: bool = True):
        stages: list[Correction] = []
        names: list[str] = []
        types: list[str] = []
        for cs in spec.correction_specs():
            cls = correction_class(cs.type, file=spec.file or None, key="corrections")
            if cls.needs_integrated_model and not integrated_model:
                continue
            if issubclass(cls, StabilizerStage) and stabilizer is not None:
                stage = StabilizerStage(stabilizer)
            else:
                stage = cls.build(cs.config, robot, dt)
            stages.append(stage)
            names.append(cs.name)
            types.append(cs.type)
        if stabilizer is not None and not any(isinstance(s, StabilizerStage) for s in stages):
            stages.append(StabilizerStage(stabilizer))
            names.append("stabilizer")
            types.append("stabilizer")
        self.stages: tuple[Correction, ...] = tuple(stages)
        self.names: tuple[str, ...] = tuple(names)
        self.types: tuple[str, ...] = tuple(types)
        self.context = CorrectionContext()
        # the stages that act on the joints after the references (`Correction.configuration` / `command`)
        self._configuring = tuple(s for s in stages if type(s).configuration is not Correction.configuration)
        self._commanding = tuple(s for s in stages if type(s).command is not Correction.command)
        stab = next((s for s in stages if isinstance(s, StabilizerStage)), None)
        self.stabilizer: Stabilizer | None = None if stab is None else stab.stabilizer
        # what logs, in order: (channel, the object whose `log` is the tick's values); the stabilizer's channel is
        # `stabilizer`, another stage's `correction_<name>`
        self._logs = tuple(("stabilizer", s.stabilizer) if isinstance(s, StabilizerStage)
                           else (f"correction_{n}", s) for s, n in zip(stages, names) if s.LOG_LABELS)
        #: the objects whose `log` each tick's `log_values` holds, in the order of `log_channels`
        self.log_sources: tuple = tuple(src for _, src in self._logs)

    def stage(self, type_: str) -> Correction | None:
        """The first stage of type `type_` (None: none)."""
        return next((s for s, t in zip(self.stages, self.types) if t == type_), None)

    # the built-in stages by their former attribute names
    @property
    def lead(self):
        return self.stage("plan_lead")

    @property
    def lift_off(self):
        return self.stage("lift_off_wait")

    @property
    def touchdown(self):
        return self.stage("touchdown_search")

    @property
    def base_feedback(self):
        """The `BaseFeedback` of the base-feedback stage (None: none)."""
        s = self.stage("base_feedback")
        return None if s is None else s.base_feedback

    @property
    def swing_tilt(self):
        return self.stage("swing_tilt")

    def reset(self, meas: Measurement, refs: References, feedback: Callable[[], ModelFeedback],
              q_model: np.ndarray | None = None) -> None:
        """At the controller's reset; `feedback()` is the model feedback at reset (called only by a stage that needs
        it, e.g. the stabilizer). Raises the stabilizer's `MissingReferenceError` when the references lack one it
        needs."""
        ctx = self.context
        ctx.meas, ctx.plan, ctx.refs, ctx.q_model = meas, refs, refs, q_model
        ctx._feedback = lambda _refs: feedback()
        for stage in self.stages:
            stage.reset(ctx)

    def apply(self, meas: Measurement, refs: References, q_model: np.ndarray | None,
              feedback: Callable[[References], ModelFeedback]) -> References:
        """This tick's references with the stages applied in order. `q_model`: the controller's model configuration
        (the integrated one for position schemes); `feedback(refs)`: its model feedback for the references
        corrected so far (called only by a stage that needs it)."""
        stages = self.stages
        if not stages:
            return refs
        ctx = self.context
        ctx.meas, ctx.plan, ctx.refs, ctx.q_model, ctx._feedback = meas, refs, refs, q_model, feedback
        for stage in stages:
            ctx.refs = stage.apply(ctx)
        return ctx.refs

    def configuration(self, q: np.ndarray) -> np.ndarray:
        """Torque mode, after `apply`: the configuration to solve at, from the measured `q` (the stages'
        `configuration` in order; `q` itself when none changes it)."""
        for stage in self._configuring:
            q = stage.configuration(self.context, q)
        return q

    def command(self, cmd: Command) -> Command:
        """Position schemes, after the solve: the command to send (the stages' `command` in order)."""
        for stage in self._commanding:
            cmd = stage.command(self.context, cmd)
        return cmd

    def status(self, out: dict) -> dict:
        """`out` with the stages' counters added (e.g. the lift-offs delayed and their summed delay [s], the
        touch-down searches made)."""
        for stage in self.stages:
            out.update(stage.status())
        return out

    def log_channels(self) -> dict[str, list[str]]:
        """The per-tick channels of the stages that log: `stabilizer`, `correction_<name>` -> labels."""
        return {ch: list(src.LOG_LABELS) for ch, src in self._logs}
