"""Video of a run: the logged states replayed through MuJoCo's offscreen renderer, with overlays, encoded as H.264
MP4 with PyAV; and key-frame strips (PNG) of a run.

The run directory is read by `replay.Replay` (shared with the browser viewer, viewer.py): only `config.json`
and `log.parquet`, so a run made on another machine renders the same; its model is the simulation's with the
URDF's visual meshes as visual-only geoms (`SimOptions(visuals=True)`), of which only the kinematics are evaluated.

Overlays (each switchable, `Overlays`): the planned footholds (the feet references, where they rest), the CoM
and its reference projected on the ground, the planned ZMP and the measured one (from the ground-truth contact
wrenches), the contact forces as arrows from each foot's centre of pressure, and a caption (scenario,
controller, mode, time).

Rendering needs an OpenGL backend, which MuJoCo picks when it is imported: `MUJOCO_GL=egl` (set by
`import wbcbench` when unset and there is no display: headless, Mesa's EGL works in software) or `osmesa`; when
none can be created the error says so in one line. Multisampling, shadows and reflections are off: in software
OpenGL they tripled the time of a frame.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError, WbcError
from .replay import FORCE_THRESHOLD, Replay, cop

__all__ = ["CAMERAS", "Overlays", "RenderError", "keyframe_strip", "render_run"]

CAMERAS = ("follow", "side", "front", "top")
#: camera azimuth / elevation [deg] and distance [m] per view (MuJoCo's free camera)
_VIEWS = {"follow": (135.0, -15.0, 3.2), "side": (90.0, -10.0, 3.5), "front": (180.0, -10.0, 3.5),
          "top": (90.0, -89.0, 4.5)}


class RenderError(WbcError):
    """No OpenGL backend, or a frame could not be rendered or encoded."""


@dataclass(frozen=True)
class Overlays:
    """Which overlays to draw (module docstring)."""

    footholds: bool = True
    com: bool = True
    zmp: bool = True
    forces: bool = True
    caption: bool = True

    @classmethod
    def none(cls) -> "Overlays":
        return cls(False, False, False, False, False)


def _prepare_for_render(model) -> None:
    """Software OpenGL (Mesa) pays for multisampling, shadows and reflections per pixel: none of them; a brighter
    headlight for the robot's dark meshes; a lighter ground, so that the overlays and the robot stand out."""
    model.vis.quality.offsamples = 0
    light = model.vis.headlight
    light.ambient[:] = (0.35, 0.35, 0.35)
    light.diffuse[:] = (0.75, 0.75, 0.75)
    light.specular[:] = (0.2, 0.2, 0.2)
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == 0:
            model.geom_rgba[g] = (0.78, 0.78, 0.74, 1.0) if model.geom_type[g] == 0 else (0.65, 0.55, 0.45, 1.0)


class _Renderer:
    """MuJoCo's offscreen renderer for a replay, with a camera and the overlays."""

    def __init__(self, replay: Replay, width: int, height: int, camera: str, overlays: Overlays):
        import mujoco

        self.mj = mujoco
        self.replay = replay
        _prepare_for_render(replay.model)
        self.data = mujoco.MjData(replay.model)
        model = replay.model
        model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
        model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
        import warnings

        try:
            with warnings.catch_warnings():  # a failing GLFW backend warns before it fails: one line is enough
                warnings.simplefilter("ignore")
                self.renderer = mujoco.Renderer(model, height, width)
        except Exception as exc:  # no display, no EGL/OSMesa library, a context that cannot be made
            raise RenderError(f"cannot create an OpenGL context with MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} "
                              f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
                              "try MUJOCO_GL=egl or MUJOCO_GL=osmesa") from None
        self.options = mujoco.MjvOption()
        for g in range(len(self.options.geomgroup)):
            self.options.geomgroup[g] = 0
        from ..sim.model import VISUAL_GROUP

        self.options.geomgroup[0] = 1  # terrain, soles
        self.options.geomgroup[VISUAL_GROUP] = 1
        flags = self.renderer.scene.flags
        for f in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX):
            flags[f] = 0
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        az, el, dist = _VIEWS[camera]
        self.camera.azimuth, self.camera.elevation, self.camera.distance = az, el, dist
        self.follow = camera != "top"
        self.overlays = overlays
        self._lookat = None
        self._footholds = replay.footholds if overlays.footholds else np.zeros((0, 3))
        self.size = (width, height)

    def frame(self, time_s: float) -> np.ndarray:
        mj, rp = self.mj, self.replay
        k = rp.tick_at(time_s)
        rp.bridge.q_to_mj(rp.q[k], self.data.qpos)
        mj.mj_kinematics(rp.model, self.data)
        base = rp.q[k, :3]
        target = np.array([base[0], base[1], 0.75])
        if self._lookat is None or not self.follow:
            self._lookat = target if self.follow else np.array([base[0], base[1], 0.5])
        else:  # a smooth follow: first-order filter at the frame rate
            self._lookat = self._lookat + 0.15 * (target - self._lookat)
        if self.follow or self._lookat is None:
            self.camera.lookat[:] = self._lookat
        self.renderer.update_scene(self.data, camera=self.camera, scene_option=self.options)
        self._draw_overlays(k)
        img = self.renderer.render()
        if self.overlays.caption:
            img = self._caption(img, rp.t[k])
        return img

    # ------------------------------------------------------------------ overlays
    def _add(self, gtype, size, pos, rgba, mat=None):
        scene = self.renderer.scene
        if scene.ngeom >= scene.maxgeom:
            return
        g = scene.geoms[scene.ngeom]
        self.mj.mjv_initGeom(g, gtype, np.asarray(size, float), np.asarray(pos, float),
                             (np.eye(3) if mat is None else mat).reshape(-1), np.asarray(rgba, np.float32))
        scene.ngeom += 1

    def _arrow(self, start, end, width, rgba):
        scene = self.renderer.scene
        if scene.ngeom >= scene.maxgeom:
            return
        g = scene.geoms[scene.ngeom]
        self.mj.mjv_initGeom(g, self.mj.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.eye(3).reshape(-1),
                             np.asarray(rgba, np.float32))
        self.mj.mjv_connector(g, self.mj.mjtGeom.mjGEOM_ARROW, width, np.asarray(start, float),
                              np.asarray(end, float))
        scene.ngeom += 1

    def _draw_overlays(self, k: int) -> None:
        mj, ov, ch = self.mj, self.overlays, self.replay.channels
        disc = mj.mjtGeom.mjGEOM_CYLINDER
        ground = 0.002
        if ov.footholds:
            for p in self._footholds:
                self._add(disc, [0.06, 0.001, 0], [p[0], p[1], p[2] + ground], [0.2, 0.8, 0.2, 0.5])
        if ov.com:
            for name, rgba in (("com", [1.0, 0.5, 0.0, 1.0]), ("com_ref", [1.0, 1.0, 1.0, 0.8])):
                c = ch.get(name)
                if c is not None and np.isfinite(c[k]).all():
                    self._add(mj.mjtGeom.mjGEOM_SPHERE, [0.025, 0, 0], [c[k, 0], c[k, 1], ground + 0.02], rgba)
        if ov.zmp:
            z = ch.get("zmp_ref")
            if z is not None and np.isfinite(z[k]).all():
                self._add(mj.mjtGeom.mjGEOM_BOX, [0.02, 0.02, 0.004], [z[k, 0], z[k, 1], z[k, 2] + ground],
                          [0.2, 0.4, 1.0, 0.9])
            zm = self.replay.measured_zmp[k] if self.replay.measured_zmp is not None else None
            if zm is not None and np.isfinite(zm).all():
                self._add(mj.mjtGeom.mjGEOM_BOX, [0.02, 0.02, 0.004], [zm[0], zm[1], zm[2] + ground],
                          [1.0, 0.1, 0.1, 0.9])
        if ov.forces:
            for name in ("contact_left", "contact_right"):
                w = ch.get(name)
                if w is None or not np.isfinite(w[k]).all() or w[k, 2] < FORCE_THRESHOLD:
                    continue
                f, m = w[k, :3], w[k, 3:]
                p = cop(f, m)
                self._arrow(p, p + f / 1000.0, 0.015, [1.0, 0.9, 0.1, 0.9])  # 1 m per 1000 N

    def _caption(self, img: np.ndarray, t: float) -> np.ndarray:
        from PIL import Image, ImageDraw

        cfg = self.replay.config
        text = (f"{cfg.get('scenario', '?')} | {cfg.get('controller', '?')} ({cfg.get('mode', '?')}) | "
                f"t = {t:6.2f} s")
        im = Image.fromarray(img)
        draw = ImageDraw.Draw(im)
        draw.rectangle([0, 0, im.width, 18], fill=(0, 0, 0))
        draw.text((6, 3), text, fill=(255, 255, 255))
        return np.asarray(im)

    def close(self) -> None:
        self.renderer.close()


def _size(size: str | tuple[int, int]) -> tuple[int, int]:
    if isinstance(size, tuple):
        w, h = size
    else:
        try:
            w, h = (int(v) for v in str(size).lower().split("x"))
        except ValueError:
            raise ConfigError(f"size '{size}' must be WIDTHxHEIGHT, e.g. 1280x720", key="--size") from None
    if not (16 <= w <= 4096 and 16 <= h <= 4096) or w % 2 or h % 2:
        raise ConfigError(f"size {w}x{h}: width and height must be even and within 16..4096", key="--size")
    return w, h


def render_run(run_dir: str | Path, out: str | Path | None = None, *, size: str | tuple[int, int] = "1280x720",
               fps: float = 30.0, speed: float = 1.0, camera: str = "follow", overlays: Overlays = Overlays(),
               progress: Callable[[float], None] | None = None) -> Path:
    """Render a run directory to an H.264 MP4 (default RUN_DIR/video.mp4); returns its path.

    `speed`: playback speed (0.5: slow motion); `fps`: frames per second of the video; a frame shows the last
    logged state at or before its time.

    Raises:
        ConfigError: not a run directory, an unreadable log, bad size / fps / speed / camera.
        RenderError: no OpenGL backend.
    """
    import av

    run_dir = Path(run_dir)
    w, h = _size(size)
    if not (np.isfinite(fps) and 1 <= fps <= 240):
        raise ConfigError(f"fps must be within 1..240, got {fps}", key="--fps")
    if not (np.isfinite(speed) and 0.05 <= speed <= 20):
        raise ConfigError(f"speed must be within 0.05..20, got {speed}", key="--speed")
    if camera not in CAMERAS:
        raise ConfigError(f"unknown camera '{camera}'; allowed: {', '.join(CAMERAS)}", key="--camera")
    replay = Replay(run_dir)
    out = Path(out) if out is not None else run_dir / "video.mp4"
    n = int(np.floor(replay.duration / speed * fps + 1e-9)) + 1
    renderer = _Renderer(replay, w, h, camera, overlays)
    try:
        container = av.open(str(out), mode="w")
    except OSError as exc:
        renderer.close()
        raise ConfigError(f"cannot write the video ({exc.strerror or exc})", file=str(out)) from None
    try:
        stream = container.add_stream("libx264" if "libx264" in av.codecs_available else "h264",
                                      rate=int(round(fps)))
        stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
        stream.options = {"crf": "23", "preset": "veryfast"}
        for i in range(n):
            img = renderer.frame(i * speed / fps)
            for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
                container.mux(packet)
            if progress is not None and i % 10 == 0:
                progress((i + 1) / n)
        for packet in stream.encode():
            container.mux(packet)
    finally:
        container.close()
        renderer.close()
    if progress is not None:
        progress(1.0)
    return out


def keyframe_strip(run_dir: str | Path, out: str | Path | None = None, *, frames: int = 6,
                   size: str | tuple[int, int] = "320x400", camera: str = "follow",
                   overlays: Overlays = Overlays(caption=False)) -> Path:
    """A PNG of `frames` frames of the run side by side, evenly spread over it (default RUN_DIR/keyframes.png)."""
    from PIL import Image

    run_dir = Path(run_dir)
    w, h = _size(size)
    replay = Replay(run_dir)
    renderer = _Renderer(replay, w, h, camera, overlays)
    try:
        times = np.linspace(0.0, replay.duration, frames)
        # the follow camera needs the frames in order to settle: step it through the run
        imgs, j = [], 0
        for t in np.arange(0.0, replay.duration + 1e-9, 1.0 / 30.0):
            img = renderer.frame(t)
            while j < frames and t + 1.0 / 30.0 > times[j]:
                imgs.append(img)
                j += 1
        while len(imgs) < frames:
            imgs.append(renderer.frame(replay.duration))
    finally:
        renderer.close()
    out = Path(out) if out is not None else run_dir / "keyframes.png"
    Image.fromarray(np.hstack(imgs)).save(out)
    return out
