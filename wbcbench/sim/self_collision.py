"""Self-collision counting: contacts between a gripper and the body parts it must not touch, per control tick.

The geoms and their collision bits come from the robot profile's `collision_check` (see `sim/model.py`). With
`SimOptions.self_collision = "physical"` the simulated model carries them and the monitor reads the simulator's
own contacts; with "detect" the simulated model is left untouched and the monitor runs MuJoCo's collision
detection (`mj_kinematics` + `mj_collision`) on a kinematic copy set to the simulated configuration.

A *contact pair* is (side, body link): the side's gripper (any of its links) touching that body link.
`SelfCollisionProbe` plugs the monitor into `wbcbench.runner.run` (`probes=`): it logs the number of pairs in
contact per tick (`self_collision.pairs`, `.left`, `.right`) and adds to the run's metrics `self_collisions`
(the number of contact events: a pair coming into contact), `self_collision_ticks` (ticks with at least one
pair in contact) and `self_collision_pairs` ("<side>:<link>" -> ticks in contact).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import ConfigError
from ..robots import Side
from .bridge import StateBridge
from .model import build_self_collision_model, self_collision_geom_name

__all__ = ["SelfCollisionMonitor", "SelfCollisionProbe"]

_SAME_LAYOUT = np.zeros(0, dtype=np.intp)  # `_qpos_map`: the copy's qpos is the simulator's, entry for entry
_NO_CONTACT = np.zeros(3)
_NO_CONTACT.flags.writeable = False


class SelfCollisionMonitor:
    """Which (side, body link) pairs are in contact in a `Simulator` now; `update()` once per control tick.

    Raises:
        ConfigError: the simulator was built with `self_collision = "off"`.
    """

    def __init__(self, sim) -> None:
        mode = sim.options.self_collision
        if mode == "off":
            raise ConfigError("self-collision counting needs SimOptions(self_collision='detect' or 'physical')",
                              key="self_collision")
        self.sim = sim
        robot = sim.robot
        if mode == "physical":
            self.model, self.data, self._bridge = sim.model, sim.data, None
        else:
            self.model = build_self_collision_model(robot)
            self.data = mujoco.MjData(self.model)
            self._bridge = StateBridge(robot, self.model)
            self._qpos_source = _qpos_map(sim, self._bridge, self.model.nq)
        m = self.model
        check = robot.profile.collision_check

        def geoms_of(link: str) -> list[int]:
            out, k = [], 0
            while (g := mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, self_collision_geom_name(link, k))) >= 0:
                out.append(g)
                k += 1
            return out

        # (geom a, geom b) -> (side, body link), both orders
        self._pairs: dict[tuple[int, int], tuple[Side, str]] = {}
        for side, c in check.items():
            eff = [g for link in c.effector for g in geoms_of(link)]
            for body in c.bodies:
                for gb in geoms_of(body):
                    for ge in eff:
                        self._pairs[(ge, gb)] = self._pairs[(gb, ge)] = (side, body)
        self.in_contact: set[tuple[Side, str]] = set()

    def update(self) -> set[tuple[Side, str]]:
        """The (side, body link) pairs in contact at the simulator's current state."""
        d = self.data
        if self._bridge is not None:
            src = self._qpos_source
            if src is not None:  # the same numbers as through pinocchio's order, in one copy
                d.qpos[:] = self.sim.data.qpos if src is _SAME_LAYOUT else self.sim.data.qpos[src]
            else:
                self._bridge.q_to_mj(self.sim.true_q(), d.qpos)
            mujoco.mj_kinematics(self.model, d)
            mujoco.mj_collision(self.model, d)
        n = d.ncon
        if not n:
            if self.in_contact:
                self.in_contact = set()
            return self.in_contact
        found = set()
        if n:
            g1, g2, dist = d.contact.geom1[:n], d.contact.geom2[:n], d.contact.dist[:n]
            pairs = self._pairs
            for a, b, depth in zip(g1.tolist(), g2.tolist(), dist.tolist()):
                hit = pairs.get((a, b))
                if hit is not None and depth < 0.0:
                    found.add(hit)
        self.in_contact = found
        return found


def _qpos_map(sim, bridge: StateBridge, nq: int) -> np.ndarray | None:
    """Indices i such that the kinematic copy's qpos is the simulator's qpos[i]: the composition of the two
    models' conversions to and from pinocchio's q (permutations both); `_SAME_LAYOUT` when that is every entry in
    place (the copy is built from the same robot), None when the simulator has no such state (then the copy is set
    through `true_q`)."""
    sb = getattr(sim, "bridge", None)
    data = getattr(sim, "data", None)
    if not isinstance(sb, StateBridge) or data is None or getattr(data, "qpos", None) is None:
        return None
    q_index = sb.q_from_mj(np.arange(len(data.qpos), dtype=float))  # simulator qpos index per pinocchio q entry
    src = np.full(nq, -1.0)
    bridge.q_to_mj(q_index, src)
    if (src < 0).any():
        return None
    if len(data.qpos) == nq and np.array_equal(src, np.arange(nq)):
        return _SAME_LAYOUT
    return src.astype(np.intp)


class SelfCollisionProbe:
    """Runner probe (`wbcbench.runner.run(..., probes=[SelfCollisionProbe()])`): per-tick gripper-body contact
    counts in the log and the self-collision metrics in the summary (module docstring)."""

    def __init__(self) -> None:
        self.monitor: SelfCollisionMonitor | None = None
        self.events = 0
        self.ticks = 0
        self.pair_ticks: dict[str, int] = {}
        self._previous: set[tuple[Side, str]] = set()

    def attach(self, sim) -> dict[str, list[str]]:
        """Called once with the simulator; returns the log channels (name -> components)."""
        self.monitor = SelfCollisionMonitor(sim)
        return {"self_collision": ["pairs", "left", "right"]}

    def values(self) -> list:
        """Called after every control tick: the channel values, in `attach`'s order."""
        now = self.monitor.update()
        if not now and not self._previous:  # the usual tick: nothing in contact, before or now
            return [_NO_CONTACT]
        self.events += len(now - self._previous)
        self._previous = now
        if now:
            self.ticks += 1
            for side, link in now:
                key = f"{side.value}:{link}"
                self.pair_ticks[key] = self.pair_ticks.get(key, 0) + 1
        left = sum(1 for s, _ in now if s is Side.LEFT)
        return [np.array([len(now), left, len(now) - left], dtype=float)]

    def metrics(self, log: dict) -> dict:
        return {"self_collisions": self.events, "self_collision_ticks": self.ticks,
                "self_collision_pairs": dict(sorted(self.pair_ticks.items()))}
