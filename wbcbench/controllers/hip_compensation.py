"""Hip flexibility compensation (paper 000 Sections 7.2.2-7.2.3): the swing foot's reference turned against the
deflection of an unmodelled torsional spring in each hip, so that the robot's real swing foot lands where the plan
puts it.

TALOS has a flexibility in each hip that the encoders do not see (about 973 N m/rad); in single support the stance
hip carries the upper body and deflects, the pelvis and the swing leg with it rotate about that hip's axis, and the
swing foot lands early or late and off its placement. With a deflection delta_h of hip h about its axis a_h through
its centre c_h, the real swing foot is the model's turned by delta_st about the stance hip and by delta_sw about the
swing hip. The stage feeds the estimated deflections forward into the swing leg: the swing foot's reference (its
position, orientation, velocity and acceleration) is turned by -delta_st about the stance hip and then by -delta_sw
about the swing hip, both as the controller's model has them (`ctx.q_model`). The same stage serves the three
controllers.

`target: hip_joint` instead acts on the hip joints themselves, so that the links, not only the swing foot, are
where the controller puts them (the pelvis kept upright on the stance hip): a hip's link angle is the encoder's
(motor side) plus delta, so a position scheme's command of that hip is lowered by delta (`Correction.command`,
after its solve) and TSID in torque mode solves at the measured configuration with delta added to that hip
(`Correction.configuration`: its model then has the links where they are, and its tasks move them). The same
estimates, hips (`hips`) and phases (single support) as for the swing foot.

Three estimates of each hip's deflection (`mode`):

* `fixed` (the paper's compensation 2): the stance hip sags by `offset` (default 20 / 973 = 0.021 rad), the sign
  being the one that lowers the swing foot; the swing hip none. In single support only, a step at lift-off.
* `torque` (the paper's compensation 1): delta = -tau_f / stiffness, tau_f the joint torque sensor's reading
  (`Measurement.tau`) of the hip joint, low-passed at `cutoff` [Hz] (first order, default 10). The motor holds the hidden
  spring's load, so that at rest tau = -stiffness delta.
* `model` (ours): delta = a_h . M_h / stiffness, M_h the moment about c_h of the external forces on the leg below
  the hip joint (the static balance of the spring), from the model at the measured configuration (`meas.q`): in
  single support, for the stance hip minus the moment of the weight of the rest of the robot (which that hip
  holds), for the swing hip the moment of its leg's weight; in double support (the two legs share the load) the
  weight of the leg's bodies between the hip and the ankle F/T sensor and the foot's reaction on the leg at the
  sensor (minus its reading). Low-passed at `cutoff` as `torque` mode. Needs no joint torque sensor. (The F/T
  reaction in single support too fed the swing foot's own motion back into its reference: at 1 kHz the IK's
  swing task oscillated against it.)

`hips`: the hips whose deflection is fed forward, `[stance, swing]` (default both). In `fixed` mode the swing hip
gets none. Only a foot with a swing reference (`References.feet`, the other foot in contact) is turned: single
support only, in every mode; the estimate itself runs in every phase (the filter of `torque` mode does not restart).
The log channel `correction_<name>` has each hip's estimate (`delta_left`, `delta_right`) [rad].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..config import Section
from ..planning.geometry import so3_exp
from ..robots import Robot
from ..side import Side
from ..types import GRAVITY, PoseReference, References
from .corrections import Correction, CorrectionContext

__all__ = ["HipCompensationConfig", "HipCompensation"]

MODES = ("fixed", "torque", "model")
HIPS = ("stance", "swing")
TARGETS = ("swing_foot", "hip_joint")


@dataclass(frozen=True)
class HipCompensationConfig:
    """Attributes:
        mode: `fixed`, `torque` or `model` (module docstring).
        stiffness: the hips' torsional stiffness [N m/rad] (> 0).
        joints: the left and right hip joints on whose axes the flexibility sits (robot joint names).
        offset: the fixed mode's deflection [rad] (> 0).
        cutoff: the torque and model modes' low-pass cutoff frequency [Hz] (> 0).
        hips: the hips fed forward, a subset of ("stance", "swing").
        target: `swing_foot` (the swing foot's reference turned) or `hip_joint` (the hip joints' command or
            model configuration shifted), module docstring.
        file, key: where `joints` was given (for the error naming an unknown joint when the stage is built).
    """

    mode: str
    stiffness: float = 973.0
    joints: tuple[str, str] = ("leg_left_2_joint", "leg_right_2_joint")
    offset: float = 20.0 / 973.0
    cutoff: float = 10.0
    hips: tuple[str, ...] = HIPS
    file: str | None = None
    key: str = "joints"
    target: str = "swing_foot"


class HipCompensation(Correction):
    """The correction stage `hip_compensation` (module docstring): `{type: hip_compensation, mode: model,
    stiffness: 973, joints: [leg_left_2_joint, leg_right_2_joint], hips: [stance, swing]}` (`offset` [rad] for
    `fixed`, `cutoff` [Hz] for `torque`; `target: hip_joint` to shift the hip joints instead of the swing foot)."""

    type = "hip_compensation"
    LOG_LABELS = ("delta_left", "delta_right")

    def __init__(self, config: HipCompensationConfig, robot: Robot, dt: float):
        super().__init__(config, robot, dt)
        m = robot.model
        self._model = m
        self._data_model, self._data_meas = m.createData(), m.createData()
        self._alpha = 1.0 - math.exp(-2.0 * math.pi * config.cutoff * dt)
        self._joint, self._axis_local, self._tau_index = {}, {}, {}
        for side, name in zip(Side, config.joints):
            j = m.getJointId(name)
            self._joint[side] = j
            self._tau_index[side] = m.joints[j].idx_v - 6
        pin.computeJointJacobians(m, self._data_model, robot.q0)
        for side, j in self._joint.items():
            J = pin.getJointJacobian(m, self._data_model, j, pin.LOCAL)[:, m.joints[j].idx_v]
            self._axis_local[side] = J[3:] / np.linalg.norm(J[3:])
        # model mode: each leg's bodies between the hip joint and the ankle F/T sensor (joint ids) and the sensor
        self._sensor = {s: m.getFrameId(robot.profile.feet[s].ft_sensor_frame) for s in Side}
        self._between = {}
        for s in Side:
            below = m.frames[self._sensor[s]].parentJoint
            self._between[s] = [k for k in range(1, m.njoints) if self._joint[s] in m.supports[k]
                                and below not in m.supports[k]]
        self._gravity = np.array([0.0, 0.0, -GRAVITY])
        self.log = np.zeros(2)
        self.reset()

    @classmethod
    def parse(cls, sec: Section) -> HipCompensationConfig:
        mode = sec.str("mode", choices=MODES)
        joints = sec.list("joints", list(HipCompensationConfig.joints))
        if len(joints) != 2 or not all(isinstance(j, str) for j in joints):
            raise sec.error("joints", f"must be the left and the right hip joint's names, got {joints!r}")
        hips = sec.list("hips", list(HIPS))
        if not hips or any(h not in HIPS for h in hips) or len(set(hips)) != len(hips):
            raise sec.error("hips", f"must be a non-empty list of stance, swing, got {hips!r}")
        return HipCompensationConfig(mode, sec.float("stiffness", 973.0, positive=True), tuple(joints),
                                     sec.float("offset", 20.0 / 973.0, positive=True),
                                     sec.float("cutoff", 10.0, positive=True), tuple(hips), sec.file,
                                     sec.key("joints"), sec.str("target", "swing_foot", choices=TARGETS))

    @classmethod
    def build(cls, config: HipCompensationConfig, robot: Robot, dt: float) -> "HipCompensation":
        from ..errors import UnknownNameError

        for name in config.joints:
            if name not in robot.joint_names:
                raise UnknownNameError("joint", name, robot.joint_names, file=config.file, key=config.key)
        return cls(config, robot, dt)

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        self._delta_f: np.ndarray | None = None  # torque and model modes: the hips' filtered estimates [rad]
        self.log[:] = 0.0
        self.max_delta = 0.0  # the largest deflection fed forward [rad]
        self._shift: tuple[tuple[int, float], ...] = ()  # target hip_joint: (joint index in tau, delta) this tick

    def status(self) -> dict:
        """The largest deflection fed forward [rad]."""
        return {"hip_compensation_max_rad": round(self.max_delta, 5)}

    # ------------------------------------------------------------------ estimates
    def _model_estimate(self, meas, contacts) -> np.ndarray:
        """Each hip's static deflection [rad] from the measured configuration (and in double support the ankle F/T
        sensors): the moment of the external forces on the leg below the hip, about the hip's axis, over the
        stiffness."""
        m, d = self._model, self._data_meas
        pin.centerOfMass(m, d, meas.q, True)  # the subtrees' masses and CoMs, with the joints' placements
        g = self._gravity
        out = np.zeros(2)
        for i, s in enumerate(Side):
            j = self._joint[s]
            Mh = d.oMi[j]
            c = Mh.translation
            if s in contacts and s.other in contacts:  # double support: the leg's gravity and the foot's reaction
                moment = np.zeros(3)
                for k in self._between[s]:
                    inertia = m.inertias[k]
                    moment += np.cross(d.oMi[k].act(inertia.lever) - c, inertia.mass * g)
                S = pin.updateFramePlacement(m, d, self._sensor[s])
                moment += np.cross(S.translation - c, -S.rotation @ meas.ft_force[s]) - S.rotation @ meas.ft_torque[s]
            elif s in contacts:  # the stance leg holds the rest of the robot: minus the rest's weight's moment
                moment = (np.cross(d.com[j] - c, d.mass[j] * g) - np.cross(d.com[0] - c, d.mass[0] * g))
            else:  # a swing leg: its own weight
                moment = np.cross(d.com[j] - c, d.mass[j] * g)
            out[i] = float((Mh.rotation @ self._axis_local[s]) @ moment) / self.config.stiffness
        return out

    def _estimate(self, meas, refs: References) -> np.ndarray:
        c = self.config
        if c.mode == "model":
            return self._filtered(self._model_estimate(meas, refs.contacts))
        if c.mode == "torque":
            if meas.tau is None:
                from ..errors import ConfigError

                raise ConfigError("hip_compensation mode torque needs the joint torque sensors' reading "
                                  "(Measurement.tau); this robot's measurement has none", key="corrections.mode")
            tau = np.array([meas.tau[self._tau_index[s]] for s in Side])
            return self._filtered(-tau / c.stiffness)
        return np.zeros(2)  # fixed: set where it is applied

    def _filtered(self, delta: np.ndarray) -> np.ndarray:
        """`delta` through the first-order low-pass of cutoff `cutoff` (started at its first value)."""
        if self._delta_f is None:
            self._delta_f = delta
        else:
            self._delta_f += self._alpha * (delta - self._delta_f)
        return self._delta_f.copy()

    # ------------------------------------------------------------------ the correction
    def apply(self, ctx: CorrectionContext) -> References:
        refs = ctx.refs
        delta = self._estimate(ctx.meas, refs)
        swing = [s for s in Side if s not in refs.contacts and s.other in refs.contacts and s in refs.feet]
        self._shift = ()
        if not swing or ctx.q_model is None:
            self.log[:] = delta if self.config.mode != "fixed" else 0.0
            return refs
        m, d = self._model, self._data_model
        pin.forwardKinematics(m, d, ctx.q_model)
        if self.config.target == "hip_joint":
            return self._joint_shift(refs, swing[0], delta)
        feet = dict(refs.feet)
        for s in swing:
            f = feet[s]
            if self.config.mode == "fixed":
                delta = np.zeros(2)
                delta[list(Side).index(s.other)] = self.config.offset * self._sag_sign(s, f.position)
            R, p = np.eye(3), np.zeros(3)  # the turn: x -> R x + p
            for hip, side in (("stance", s.other), ("swing", s)):
                if hip not in self.config.hips:
                    continue
                Mh = d.oMi[self._joint[side]]
                a, c = Mh.rotation @ self._axis_local[side], Mh.translation
                Rh = so3_exp(-delta[list(Side).index(side)] * a)
                R, p = Rh @ R, Rh @ (p - c) + c
            self.max_delta = max(self.max_delta, float(np.max(np.abs(delta))))
            feet[s] = PoseReference(R @ f.position + p, None if f.rotation is None else R @ f.rotation,
                                    np.concatenate((R @ f.velocity[:3], R @ f.velocity[3:])),
                                    np.concatenate((R @ f.acceleration[:3], R @ f.acceleration[3:])))
        self.log[:] = delta
        return refs.corrected(refs.com, refs.targets, refs.wrench_targets, refs.contact_poses, feet=feet)

    def _joint_shift(self, refs: References, s: Side, delta: np.ndarray) -> References:
        """Target hip_joint: this tick's (joint, delta) of the hips fed forward, for `configuration` / `command`."""
        if self.config.mode == "fixed":
            delta = np.zeros(2)
            delta[list(Side).index(s.other)] = self.config.offset * self._sag_sign(s, refs.feet[s].position)
        hips = {"stance": s.other, "swing": s}
        self._shift = tuple((self._tau_index[hips[h]], float(delta[list(Side).index(hips[h])]))
                            for h in self.config.hips)
        self.max_delta = max(self.max_delta, max(abs(d) for _, d in self._shift))
        self.log[:] = delta
        return refs

    def configuration(self, ctx: CorrectionContext, q: np.ndarray) -> np.ndarray:
        """Target hip_joint, torque mode: the measured configuration with each fed-forward hip's delta added (the
        link's angle)."""
        if not self._shift:
            return q
        q = q.copy()
        for i, d in self._shift:
            q[7 + i] += d
        return q

    def command(self, ctx: CorrectionContext, cmd):
        """Target hip_joint, position schemes: each fed-forward hip's commanded angle lowered by its delta (the
        motor side that puts the link where the controller wants it)."""
        if not self._shift or cmd.q is None:
            return cmd
        q = cmd.q.copy()
        for i, d in self._shift:
            q[i] -= d
        return type(cmd)(tau=cmd.tau, q=q, v=cmd.v)

    def _sag_sign(self, swing: Side, foot: np.ndarray) -> float:
        """+1 when a positive rotation about the stance hip's axis lowers the swing foot at `foot`, else -1 (the
        model's kinematics in `_data_model`)."""
        Mh = self._data_model.oMi[self._joint[swing.other]]
        a, c = Mh.rotation @ self._axis_local[swing.other], Mh.translation
        dz = np.cross(a, foot - c)[2]  # d(foot z)/d(angle)
        return 1.0 if dz < 0.0 else -1.0
