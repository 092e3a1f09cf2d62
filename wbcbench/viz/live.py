"""Live view of a run in the browser (`wbcbench run ... --view`, `wbcbench teleop ... --view`): a runner probe that
publishes the simulator's true state to a viser server at a display rate.

The control loop only hands over a snapshot, at most `rate` times per second of wall-clock time (a clock read per
tick, a configuration copy per published frame); a background thread moves the robot's meshes in the browser.
The loop never waits for the browser or the thread: a snapshot not yet shown is replaced by the next. A frame
sends the base's pose and the rotation of each body that turned by more than `TOLERANCE` in its parent's frame
(scene3d.RobotNodes): each is a message, and viser's handling of messages is most of the view's cost. The
references' frame targets (teleoperation: the operator's retargeted hands and head) are shown as axes, through
the runner's `observe(t, refs)` probe hook.

The robot's visual meshes come from the simulation's model rebuilt with `SimOptions(visuals=True)` (same joints,
so the same configuration), made when the probe is attached, before the first tick.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from .scene3d import RobotNodes, add_terrain, move, start_server, stop_server

__all__ = ["LiveView"]

#: [m] (and about rad / 2 of orientation) a body that moved less in its parent's frame since it was last sent is
#: not sent again
TOLERANCE = 2e-4


class LiveView:
    """A runner probe (`wbcbench.runner.run(probes=...)`) showing the run in the browser; logs nothing.

    The server starts at construction, so a port in use is reported before the run (ConfigError naming
    `key`). Call `close()` when the run is over.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, rate: float = 30.0, key: str = "--view-port"):
        self.server = start_server(host, port, "wbcbench live", key=key)
        self.host, self.port = host, port
        self.period = 1.0 / rate
        self._next = 0.0
        self._refs = None
        self._slot = None
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = None
        self.published = 0  # frames handed over by the loop
        self.shown = 0  # frames sent to the browser

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    # ------------------------------------------------------------------ probe interface (control loop)
    def attach(self, sim) -> dict:
        import mujoco

        from ..sim.bridge import StateBridge
        from ..sim.model import SimOptions, build_mujoco_model

        self._sim = sim
        model = build_mujoco_model(sim.robot, sim.terrain, sim.mode, SimOptions(visuals=True))
        self._model, self._data = model, mujoco.MjData(model)
        self._bridge = StateBridge(sim.robot, model)
        scene = self.server.scene
        add_terrain(scene, "/terrain", model)
        self.robot = RobotNodes(scene, "/robot", model)
        self._targets = {}
        self._next_caption = 0.0
        self.caption = self.server.gui.add_markdown("waiting for the first tick")
        q = sim.true_q()
        self.server.initial_camera.look_at = (q[0] + 0.3, q[1], 0.7)
        self.server.initial_camera.position = (q[0] + 3.0, q[1] - 3.0, 1.9)
        self._show(0.0, q, {})
        self._wall0 = time.perf_counter()
        self._thread = threading.Thread(target=self._publish_loop, name="wbcbench-live", daemon=True)
        self._thread.start()
        return {}

    def observe(self, t: float, refs) -> None:
        """The references handed to the controller this tick (the runner's probe hook)."""
        self._refs = refs

    def values(self) -> tuple:
        now = time.perf_counter()
        if now >= self._next:
            self._next = now + self.period
            targets = {}
            if self._refs is not None:
                for name, target in self._refs.targets.items():
                    if not hasattr(target, "position"):  # a joint-space (posture) reference: no frame to draw
                        continue
                    targets[name] = (np.array(target.position, dtype=float),
                                     None if target.rotation is None else np.array(target.rotation, dtype=float))
            self._slot = (self._sim.t, self._sim.true_q(), targets)
            self.published += 1
            self._wake.set()
        return ()

    def metrics(self, log) -> dict:
        return {}

    # ------------------------------------------------------------------ browser side (own thread)
    def _publish_loop(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(0.5)
            self._wake.clear()
            slot, self._slot = self._slot, None
            if slot is not None:
                self._show(*slot)

    def _show(self, t: float, q: np.ndarray, targets: dict) -> None:
        import mujoco

        self._bridge.q_to_mj(q, self._data.qpos)
        mujoco.mj_kinematics(self._model, self._data)
        with self.server.atomic():
            self.robot.set(self._data, tolerance=TOLERANCE)
            for name, (p, R) in targets.items():
                frame = self._targets.get(name)
                if frame is None:
                    frame = self._targets[name] = self.server.scene.add_frame(
                        f"/targets/{name}", axes_length=0.12, axes_radius=0.008)
                    self.server.scene.add_label(f"/targets/{name}/label", name, anchor="bottom-center")
                move(frame, p)
                if R is not None:
                    wxyz = np.zeros(4)
                    mujoco.mju_mat2Quat(wxyz, R.reshape(-1))
                    frame.wxyz = wxyz
            now = time.perf_counter()
            if now >= self._next_caption:  # twice a second: each is one more message to send
                self._next_caption = now + 0.5
                wall = now - getattr(self, "_wall0", now)
                self.caption.content = (f"**t = {t:7.3f} s** (simulated), wall {wall:6.1f} s"
                                        + (f", {t / wall:4.2f} x real time" if wall > 0.5 else ""))
        self.shown += 1

    def close(self) -> None:
        """Stop the publishing thread and the server (idempotent)."""
        if not self._stop.is_set():
            self._stop.set()
            self._wake.set()
            if self._thread is not None:
                self._thread.join(timeout=2.0)
            stop_server(self.server)
