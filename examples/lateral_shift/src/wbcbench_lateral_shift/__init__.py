"""A plan correction written outside wbcbench: `{type: lateral_shift, offset: 0.02, ramp: 1.0}` in a task set's
`corrections:` list moves the CoM and ZMP references by `offset` [m] along the world y axis, faded in over `ramp` [s]."""

from dataclasses import replace

import numpy as np
from wbcbench import Correction, PointReference


class LateralShift(Correction):
    type = "lateral_shift"
    LOG_LABELS = ("x", "y", "z")  # logged per tick (channel correction_lateral_shift): the CoM reference passed on

    @classmethod
    def parse(cls, sec):  # the settings from the task set's entry (a key it does not read is an error)
        return sec.float("offset"), sec.float("ramp", 1.0, positive=True)

    def reset(self, ctx):
        self.log = np.full(3, np.nan)

    def apply(self, ctx):
        refs, (offset, ramp) = ctx.refs, self.config
        if refs.com is None:
            return refs
        d = np.array([0.0, min(refs.t / ramp, 1.0) * offset, 0.0])
        v = np.array([0.0, offset / ramp if refs.t < ramp else 0.0, 0.0])
        com = PointReference(refs.com.position + d, refs.com.velocity + v, refs.com.acceleration)
        self.log[:] = com.position
        return replace(refs, com=com, zmp=None if refs.zmp is None else refs.zmp + d)
