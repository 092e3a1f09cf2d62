"""A run directory made ready to show, for the MP4 renderer (render.py) and the browser viewer (viewer.py).

Only the run directory is read (`config.json` for the robot and the scene, `log.parquet` for the states and the
overlay channels), so a run made on another machine replays the same. The model is the simulation's with the
URDF's visual meshes added as visual-only geoms (`SimOptions(visuals=True)`); only its kinematics are evaluated.

The overlays' data are computed here once for both: the planned footholds (where the feet references rest), the
measured ZMP (from the ground-truth contact wrenches), the support polygon (the sole corners of the feet that
carry weight).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import ConfigError

__all__ = ["FORCE_THRESHOLD", "Replay", "cop"]

#: [N] a foot (or the robot) carries weight above this vertical force: its centre of pressure is defined
FORCE_THRESHOLD = 5.0
_OVERLAY_CHANNELS = ("com", "com_ref", "zmp_ref", "foot_ref_left", "foot_ref_right", "contact_left",
                     "contact_right")


class Replay:
    """A run directory: its robot, its visual MuJoCo model, the states per tick (`t`, `q`), the overlay channels.

    `model_builder(robot, terrain) -> MjModel` makes the model (default: the simulation's with the visual meshes).

    Raises:
        ConfigError: no log.parquet, an unreadable config.json or log, a log that lacks the states or does not
            fit the robot.
    """

    def __init__(self, run_dir: str | Path, model_builder: Callable | None = None):
        from ..recorder import channel, read_log
        from ..robots import load_robot
        from ..scene import Box, Terrain
        from ..sim.bridge import StateBridge
        from ..sim.model import SimOptions, build_mujoco_model
        from ..types import ActuationMode

        run_dir = Path(run_dir)
        self.run_dir = run_dir
        cfg_path, log_path = run_dir / "config.json", run_dir / "log.parquet"
        if not log_path.is_file():
            raise ConfigError("not a run directory: no log.parquet", file=str(run_dir))
        try:
            cfg = json.loads(cfg_path.read_text())
        except (OSError, ValueError) as exc:
            raise ConfigError(f"cannot read the run's config.json ({exc})", file=str(cfg_path)) from None
        try:
            log = read_log(log_path)
        except Exception as exc:  # pyarrow raises several kinds on a damaged file
            raise ConfigError(f"cannot read the log ({type(exc).__name__}: {str(exc).splitlines()[0]})",
                              file=str(log_path)) from None
        profile = cfg.get("robot_profile")
        self.robot = load_robot(profile if profile and Path(profile).is_file() else cfg.get("robot", "talos"))
        scene = cfg.get("scene")
        if scene is not None:
            terrain = Terrain(kind=scene.get("kind", "flat"), floor=scene.get("floor", True),
                              boxes=tuple(Box(tuple(b["center"]), tuple(b["size"]), tuple(b.get("rpy", (0, 0, 0))),
                                              b.get("name", "")) for b in scene.get("boxes", ())),
                              friction=scene.get("friction", 1.0))
        else:  # runs from before the scene was recorded: the scenario file, if it is still there
            terrain = Terrain()
            file = cfg.get("scenario_file")
            if file and Path(file).is_file():
                from ..config import Section, load_yaml
                from ..scene import parse_terrain

                terrain = parse_terrain(Section(load_yaml(file), file).section("terrain", {}))
        self.config = cfg
        self.terrain = terrain
        # the simulation's model with the visual meshes, or one made for drawing (`render._visual_model`)
        self.model = (model_builder(self.robot, terrain) if model_builder is not None else
                      build_mujoco_model(self.robot, terrain, ActuationMode.TORQUE, SimOptions(visuals=True)))
        self.bridge = StateBridge(self.robot, self.model)
        try:
            self.t = np.asarray(log["t"], dtype=float)
            self.q = channel(log, "q")
        except KeyError as exc:
            raise ConfigError(f"the log lacks {exc}", file=str(log_path)) from None
        if len(self.t) == 0 or self.q.shape[1] != self.robot.model.nq:
            raise ConfigError(f"the log has {len(self.t)} ticks of a {self.q.shape[1]}-dof configuration; the "
                              f"robot '{self.robot.name}' has nq = {self.robot.model.nq}", file=str(log_path))
        self.log = log
        self.channels = {name: _maybe(channel, log, name) for name in _OVERLAY_CHANNELS}
        self.footholds = planned_footholds(self.channels)
        self.measured_zmp = measured_zmp(self.channels)

    def worker_state(self) -> dict:
        """What a render worker process needs besides the model (which it reads from a file): config, times,
        channels and overlay data; not the robot, the log or the states (the frame plan carries those)."""
        return {k: v for k, v in self.__dict__.items()
                if k not in ("robot", "bridge", "log", "q", "model", "_pin_data")}

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def label(self) -> str:
        """'scenario / controller (mode)' from the config."""
        c = self.config
        return f"{c.get('scenario', '?')} / {c.get('controller', '?')} ({c.get('mode', '?')})"

    def tick_at(self, time_s: float) -> int:
        """The last logged tick at or before `time_s` [s] (the first one before the log starts)."""
        return int(min(np.searchsorted(self.t, time_s - 1e-9), len(self.t) - 1))

    def support_polygon(self, k: int) -> np.ndarray:
        """(n, 2) counter-clockwise corners [m] of the convex hull of the soles that carry weight at tick k (the
        ground-truth contact force above FORCE_THRESHOLD); (0, 2) when none does."""
        import pinocchio as pin

        from ..estimation.fall import convex_hull
        from ..robots import Side

        robot = self.robot
        if not hasattr(self, "_pin_data"):
            self._pin_data = robot.model.createData()
        pts = []
        loaded = [s for s in Side if (w := self.channels.get(f"contact_{s.value}")) is not None
                  and np.isfinite(w[k]).all() and w[k, 2] > FORCE_THRESHOLD]
        if not loaded:
            return np.zeros((0, 2))
        pin.framesForwardKinematics(robot.model, self._pin_data, self.q[k])
        corners = robot.profile.sole.corners
        for s in loaded:
            M = self._pin_data.oMf[robot.sole_frame_id(s)]
            pts.append((M.rotation @ corners.T).T[:, :2] + M.translation[:2])
        return convex_hull(np.vstack(pts))


def _maybe(fn, log, name):
    try:
        return fn(log, name)
    except KeyError:
        return None


def planned_footholds(channels: dict) -> np.ndarray:
    """(n, 3) [m] where the feet references rest: the consecutive distinct resting positions of each foot."""
    out = []
    for name in ("foot_ref_left", "foot_ref_right"):
        P = channels.get(name)
        if P is None:
            continue
        P = P[np.isfinite(P).all(axis=1)]
        if len(P) < 2:
            continue
        still = np.r_[True, np.linalg.norm(np.diff(P, axis=0), axis=1) < 1e-6]
        rests = P[still]
        keep = [rests[0]]
        for p in rests[1:]:
            if np.linalg.norm(p - keep[-1]) > 0.02:
                keep.append(p)
        out += keep
    return np.array(out) if out else np.zeros((0, 3))


def cop(f: np.ndarray, m: np.ndarray, height: float | np.ndarray = 0.0) -> np.ndarray:
    """The point of the plane z = height about which the wrench (force f, moment m about the world origin) has no
    horizontal moment: the centre of pressure / ZMP on that plane [m]. f, m: (3,) or (n, 3)."""
    f, m = np.asarray(f, float), np.asarray(m, float)
    z = np.broadcast_to(np.asarray(height, float), f[..., 2].shape)
    return np.stack([(-m[..., 1] + z * f[..., 0]) / f[..., 2], (m[..., 0] + z * f[..., 1]) / f[..., 2], z], axis=-1)


def measured_zmp(channels: dict) -> np.ndarray | None:
    """(ticks, 3) [m] the ZMP of the summed ground-truth contact wrenches, on the plane of the planned ZMP (z = 0
    without one); NaN where the robot carries less than FORCE_THRESHOLD. None without contact channels."""
    ws = [channels[n] for n in ("contact_left", "contact_right") if channels.get(n) is not None]
    if not ws:
        return None
    w = np.sum(ws, axis=0)
    z = channels.get("zmp_ref")
    height = np.where(np.isfinite(z[:, 2]), z[:, 2], 0.0) if z is not None else np.zeros(len(w))
    ok = np.isfinite(w).all(axis=1) & (w[:, 2] >= FORCE_THRESHOLD)
    out = np.full((len(w), 3), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        out[ok] = cop(w[ok, :3], w[ok, 3:], height[ok])
    return out
