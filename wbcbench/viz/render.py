"""Video of a run: the logged states replayed through MuJoCo's offscreen renderer, with overlays, encoded as H.264
MP4 with PyAV; and key-frame strips (PNG) of a run.

The run directory is read by `replay.Replay` (shared with the browser viewer, viewer.py): only `config.json`
and `log.parquet`, so a run made on another machine renders the same; its model is the simulation's with the
URDF's visual meshes as visual-only geoms (`SimOptions(visuals=True)`), made for drawing by `_visual_model`, of
which only the kinematics are evaluated.

Overlays (each switchable, `Overlays`): the planned footholds (the feet references, where they rest), the CoM
and its reference projected on the ground, the planned ZMP and the measured one (from the ground-truth contact
wrenches), the contact forces as arrows from each foot's centre of pressure, and a caption (scenario,
controller, mode, time).

Rendering needs an OpenGL backend, which MuJoCo picks when it is imported: `MUJOCO_GL=egl` (set by
`import wbcbench` when unset and there is no display: headless, Mesa's EGL works in software) or `osmesa`; when
none can be created the error says so in one line. Multisampling, shadows and reflections are off: in software
OpenGL they tripled the time of a frame. The scene is the visual model's (`SimOptions(visuals=True)`): a sky that
fades from blue to white at the horizon and a checker floor of 0.5 m squares, so that motion and depth read.

Speed (software OpenGL draws every triangle on the CPU): the visual meshes are drawn from simplified copies
(vertex clustering on a 1.5 cm grid that keeps differently facing surfaces apart, `simplify_meshes`: TALOS'
159,000 faces become about 82,000, invisible at the video's distance); the infinite ground plane, which MuJoCo
draws as a fine grid out to the far clipping plane, is drawn as one 200 m square; the camera path is computed
before rendering (`_FramePlan`), so that frames can be rendered out of order by several worker processes (each
its own model copy and OpenGL context, interleaved frames) feeding one encoder in order, pixel-identical to one
process. A video's frames are read from OpenGL as BGR, the order FFmpeg converts to YUV fastest, into reused
buffers whose rows are flipped by a view, not a copy, and encoded (x264 preset ultrafast) in a thread of its own
while the next frame is drawn (`_Encoder`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import ConfigError, WbcError
from .replay import FORCE_THRESHOLD, Replay, cop

__all__ = ["CAMERAS", "Overlays", "RenderError", "keyframe_strip", "render_run", "simplify_meshes"]

CAMERAS = ("follow", "side", "front", "top")
#: camera azimuth / elevation [deg] and distance [m] per view (MuJoCo's free camera)
_VIEWS = {"follow": (135.0, -15.0, 3.2), "side": (90.0, -10.0, 3.5), "front": (180.0, -10.0, 3.5),
          "top": (90.0, -89.0, 4.5)}
MESH_CELL_M = 0.015
"""Grid cell [m] of the visual meshes' simplification (`simplify_meshes`); 0 draws the full meshes."""
_FLOOR_HALF_SIZE_M = 100.0
"""Half size [m] of the square the infinite ground plane is drawn as (MuJoCo's far plane is 50 model extents)."""


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


_MODEL_FORMAT = 2
"""Version of `_visual_model`'s changes to the simulation model: bump it when they change (cache key)."""
_MODELS: dict = {}
"""Visual models built or read in this process, by cache key (`_visual_model` hands out copies)."""


def cache_dir() -> Path | None:
    """Where visual models are kept between runs: $WBCBENCH_CACHE_DIR, else $XDG_CACHE_HOME/wbcbench or
    ~/.cache/wbcbench (an empty WBCBENCH_CACHE_DIR: no disk cache)."""
    root = os.environ.get("WBCBENCH_CACHE_DIR")
    if root is None:
        root = str(Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "wbcbench")
    return Path(root) / "render-models" if root else None


def _visual_model(robot, terrain, mesh_cell: float):
    """The simulation's model of `robot` on `terrain` with the URDF's visual meshes, made for drawing: no
    multisampling, a brighter headlight, a lighter ground drawn as one square, meshes simplified (`mesh_cell`).

    Building it (reading the meshes, compiling) takes seconds, drawing a frame milliseconds: the model is kept as
    MJB, in this process and on disk (`cache_dir`), under a key made of everything it is built from (model file and
    profile text, the model-building code, the terrain, the cell, MuJoCo's version).
    """
    import copy
    import hashlib

    import mujoco

    from ..sim import model as sim_model
    from ..sim.model import SimOptions, build_mujoco_model
    from ..types import ActuationMode

    h = hashlib.sha256()
    for part in (robot.files.path.read_bytes(), Path(robot.profile.file).read_bytes() if robot.profile.file else b"",
                 Path(sim_model.__file__).read_bytes(), repr(terrain).encode(),
                 f"{mesh_cell}|{mujoco.__version__}|{_MODEL_FORMAT}".encode()):
        h.update(hashlib.sha256(part).digest())
    key = h.hexdigest()[:32]
    if key in _MODELS:
        return copy.deepcopy(_MODELS[key])
    cache = cache_dir()
    if cache is not None and (cache / f"{key}.mjb").is_file():
        try:
            _MODELS[key] = mujoco.MjModel.from_binary_path(str(cache / f"{key}.mjb"))
            return copy.deepcopy(_MODELS[key])
        except Exception:  # a damaged cache file: build it again
            pass
    model = build_mujoco_model(robot, terrain, ActuationMode.TORQUE, SimOptions(visuals=True))
    # software OpenGL (Mesa) pays for multisampling, shadows and reflections per pixel: none of them
    model.vis.quality.offsamples = 0
    light = model.vis.headlight  # brighter than MuJoCo's default for the robot's dark meshes
    light.ambient[:] = (0.35, 0.35, 0.35)
    light.diffuse[:] = (0.75, 0.75, 0.75)
    light.specular[:] = (0.2, 0.2, 0.2)
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != 0:
            continue
        plane = model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE
        # a lighter ground, so that the overlays and the robot stand out (a textured floor keeps its checker)
        if model.geom_matid[g] < 0:
            model.geom_rgba[g] = (0.78, 0.78, 0.74, 1.0) if plane else (0.65, 0.55, 0.45, 1.0)
        if plane and not model.geom_size[g, :2].all():  # infinite: MuJoCo draws a fine grid out to the far plane
            model.geom_size[g] = (_FLOOR_HALF_SIZE_M, _FLOOR_HALF_SIZE_M, 10.0)
    if mesh_cell > 0:
        simplify_meshes(model, mesh_cell)
    if cache is not None:
        try:  # written whole then renamed: processes building the same model at once do not clash
            cache.mkdir(parents=True, exist_ok=True)
            part = cache / f"{key}.{os.getpid()}.part"
            mujoco.mj_saveModel(model, str(part), None)
            os.replace(part, cache / f"{key}.mjb")
        except Exception:  # no writable cache: built each time
            pass
    _MODELS[key] = model
    return copy.deepcopy(model)


def _render_replay(run_dir: str | Path, mesh_cell: float = MESH_CELL_M) -> Replay:
    """A run directory with the model made for drawing (`_visual_model`)."""
    return Replay(run_dir, model_builder=lambda robot, terrain: _visual_model(robot, terrain, mesh_cell))


def simplify_meshes(model, cell: float) -> int:
    """Replace each mesh of `model` (in place, for drawing only) by a vertex clustering of it; returns the number
    of faces left.

    The vertices falling in one cell of a `cell` [m] grid and facing the same way (the axis and sign of their
    normal's largest component, so that the two sides of a thin shell stay apart) merge into their mean, with the
    mean of their normals; faces that collapse or repeat are dropped. The simplified mesh is written at the start
    of the mesh's own arrays and its face count lowered, so the renderer uploads fewer triangles; the model's
    other arrays (and the simulation, which never sees this model) are untouched.
    """
    total = 0
    for i in range(model.nmesh):
        va, nv = int(model.mesh_vertadr[i]), int(model.mesh_vertnum[i])
        fa, nf = int(model.mesh_faceadr[i]), int(model.mesh_facenum[i])
        na, nn = int(model.mesh_normaladr[i]), int(model.mesh_normalnum[i])
        if nv == 0 or nf == 0 or nn != nv or model.mesh_texcoordnum[i]:  # one normal per vertex, no texture
            total += nf
            continue
        V = model.mesh_vert[va:va + nv].astype(float)
        N = model.mesh_normal[na:na + nn].astype(float)
        F = model.mesh_face[fa:fa + nf]
        axis = np.argmax(np.abs(N), axis=1)
        facing = 2 * axis + (N[np.arange(nv), axis] > 0)
        cells = np.floor((V - V.min(axis=0)) / cell).astype(np.int64)
        _, label, count = np.unique(np.c_[cells, facing], axis=0, return_inverse=True, return_counts=True)
        label = label.ravel()
        k = len(count)
        V2 = np.zeros((k, 3))
        np.add.at(V2, label, V)
        V2 /= count[:, None]
        N2 = np.zeros((k, 3))
        np.add.at(N2, label, N)
        N2 /= np.maximum(np.linalg.norm(N2, axis=1, keepdims=True), 1e-12)
        G = label[F]
        G = G[(G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 0] != G[:, 2])]
        _, first = np.unique(np.sort(G, axis=1), axis=0, return_index=True)
        G = G[np.sort(first)]
        model.mesh_vert[va:va + k] = V2
        model.mesh_normal[na:na + k] = N2
        model.mesh_face[fa:fa + len(G)] = G
        model.mesh_facenormal[fa:fa + len(G)] = G
        model.mesh_facenum[i] = len(G)
        total += len(G)
    return total


_CAPTION_ROWS = 19
"""Height [px] of the caption's black band."""


def _camera_step(lookat: np.ndarray | None, base: np.ndarray, follow: bool) -> np.ndarray:
    """The camera's point of interest for the next frame, the base at `base`: a first-order filter of the base's
    horizontal position at 0.75 m height (follow cameras; the first frame looks straight at it), or the first
    frame's base at 0.5 m height for the fixed camera."""
    if not follow:
        return lookat if lookat is not None else np.array([base[0], base[1], 0.5])
    target = np.array([base[0], base[1], 0.75])
    return target if lookat is None else lookat + 0.15 * (target - lookat)


class _FramePlan(NamedTuple):
    """What each frame of a video shows, computed before any is rendered (so they can be rendered in any order).

    Attributes:
        ticks: (n,) log tick per frame.
        qpos: (n, model.nq) MuJoCo configuration per frame.
        lookat: (n, 3) camera point of interest per frame [m].
    """

    ticks: np.ndarray
    qpos: np.ndarray
    lookat: np.ndarray


def _plan(replay: Replay, times: np.ndarray, camera: str) -> _FramePlan:
    ticks = np.array([replay.tick_at(t) for t in times], dtype=int)
    qpos = np.zeros((len(ticks), replay.model.nq))
    lookat = np.zeros((len(ticks), 3))
    look = None
    for i, k in enumerate(ticks):
        replay.bridge.q_to_mj(replay.q[k], qpos[i])
        look = lookat[i] = _camera_step(look, replay.q[k, :3], camera != "top")
    return _FramePlan(ticks, qpos, lookat)


class _Renderer:
    """MuJoCo's offscreen renderer for a replay, with a camera and the overlays."""

    def __init__(self, replay: Replay, width: int, height: int, camera: str, overlays: Overlays):
        import mujoco

        self.mj = mujoco
        self.replay = replay
        self.data = mujoco.MjData(replay.model)
        model = replay.model
        model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
        model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
        import warnings

        self.gl, self.context = None, None
        try:
            from mujoco import gl_context

            with warnings.catch_warnings():  # a failing GLFW backend warns before it fails: one line is enough
                warnings.simplefilter("ignore")
                if getattr(gl_context, "GLContext", None) is None:
                    raise RuntimeError("no OpenGL backend")
                self.gl = gl_context.GLContext(width, height)
                self.gl.make_current()
                self.context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        except Exception as exc:  # no display, no EGL/OSMesa library, a context that cannot be made
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    self.close()
                except Exception:  # a half-made context: nothing more to free
                    pass
            raise RenderError(f"cannot create an OpenGL context with MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} "
                              f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
                              "try MUJOCO_GL=egl or MUJOCO_GL=osmesa") from None
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self.context)
        self.scene = mujoco.MjvScene(model, maxgeom=10000)
        self.rect = mujoco.MjrRect(0, 0, width, height)
        self.options = mujoco.MjvOption()
        for g in range(len(self.options.geomgroup)):
            self.options.geomgroup[g] = 0
        from ..sim.model import VISUAL_GROUP

        self.options.geomgroup[0] = 1  # terrain, soles
        self.options.geomgroup[VISUAL_GROUP] = 1
        flags = self.scene.flags
        for f in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION):
            flags[f] = 0
        flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = 1  # the model's sky gradient (a model without one: black)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        az, el, dist = _VIEWS[camera]
        self.camera.azimuth, self.camera.elevation, self.camera.distance = az, el, dist
        self.follow = camera != "top"
        self.overlays = overlays
        self._lookat = None
        self._font = None
        self._footholds = replay.footholds if overlays.footholds else np.zeros((0, 3))
        self.size = (width, height)

    def frame(self, time_s: float) -> np.ndarray:
        """The frame at `time_s`, the follow camera filtered through the frames asked so far."""
        rp = self.replay
        k = rp.tick_at(time_s)
        qpos = np.zeros(rp.model.nq)
        rp.bridge.q_to_mj(rp.q[k], qpos)
        self._lookat = _camera_step(self._lookat, rp.q[k, :3], self.follow)
        return self.draw(k, qpos, self._lookat)

    def draw(self, k: int, qpos: np.ndarray, lookat: np.ndarray, out: np.ndarray | None = None,
             bgr: bool = False) -> np.ndarray:
        """The frame of tick `k`: the robot at MuJoCo configuration `qpos`, the camera looking at `lookat`; an RGB
        image (BGR with `bgr`: what the video encoder converts fastest).

        The pixels are read into `out` (a (height, width, 3) uint8 array, bottom row first as OpenGL gives them),
        or a new array, and the image returned is a view of it with the rows flipped (no copy).
        """
        mj, rp = self.mj, self.replay
        self.data.qpos[:] = qpos
        mj.mj_kinematics(rp.model, self.data)
        self.camera.lookat[:] = lookat
        mj.mjv_updateScene(rp.model, self.data, self.options, None, self.camera, mj.mjtCatBit.mjCAT_ALL, self.scene)
        self._draw_overlays(k)
        self.gl.make_current()
        mj.mjr_render(self.rect, self.scene, self.context)
        w, h = self.size
        buf = out if out is not None else np.empty((h, w, 3), np.uint8)
        if bgr and self.context.offSamples == 0:  # straight from the framebuffer in the order asked
            from OpenGL import GL

            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self.context.offFBO)
            GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
            GL.glReadPixels(0, 0, w, h, GL.GL_BGR, GL.GL_UNSIGNED_BYTE, buf)
        else:
            mj.mjr_readPixels(buf, None, self.rect, self.context)
            if bgr:
                buf[:] = buf[:, :, ::-1]
        img = buf[::-1]
        if self.overlays.caption:
            self._caption(img, rp.t[k])
        return img

    # ------------------------------------------------------------------ overlays
    def _add(self, gtype, size, pos, rgba, mat=None):
        scene = self.scene
        if scene.ngeom >= scene.maxgeom:
            return
        g = scene.geoms[scene.ngeom]
        self.mj.mjv_initGeom(g, gtype, np.asarray(size, float), np.asarray(pos, float),
                             (np.eye(3) if mat is None else mat).reshape(-1), np.asarray(rgba, np.float32))
        scene.ngeom += 1

    def _arrow(self, start, end, width, rgba):
        scene = self.scene
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

    def _caption(self, img: np.ndarray, t: float) -> None:
        """The caption drawn in place on the image's top band (only that band goes through PIL; dark grey on light
        grey: the same in RGB and BGR)."""
        from PIL import Image, ImageDraw

        cfg = self.replay.config
        text = (f"{cfg.get('scenario', '?')} | {cfg.get('controller', '?')} ({cfg.get('mode', '?')}) | "
                f"t = {t:6.2f} s")
        if self._font is None:  # PIL's bitmap font: a tenth of the time of its default FreeType one per frame
            from PIL import ImageFont

            self._font = ImageFont.load_default_imagefont()
        band = Image.new("RGB", (img.shape[1], _CAPTION_ROWS), (236, 236, 236))
        ImageDraw.Draw(band).text((6, 3), text, fill=(25, 25, 25), font=self._font)
        img[:_CAPTION_ROWS] = np.asarray(band)

    def close(self) -> None:
        """Free the OpenGL context (the MuJoCo context first, while current)."""
        if self.gl is not None:
            self.gl.make_current()
        if self.context is not None:
            self.context.free()
            self.context = None
        if self.gl is not None:
            self.gl.free()
            self.gl = None


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


def _render_worker(state: dict, model_file: str, plan: _FramePlan, first: int, step: int, size: tuple[int, int],
                   camera: str, overlays: Overlays, bgr: bool, conn) -> None:
    """A render process: frames first, first + step, ... of `plan`, each sent as the raw bytes of its pixels
    (`_Renderer.draw`'s buffer: bottom row first) on `conn`; an error is sent as one message starting with b"E"
    (shorter than a frame) instead. The replay is rebuilt from its `worker_state` and the model saved by the parent
    (MJB)."""
    try:
        import mujoco

        replay = Replay.__new__(Replay)
        replay.__dict__.update(state)
        replay.model = mujoco.MjModel.from_binary_path(model_file)
        renderer = _Renderer(replay, size[0], size[1], camera, overlays)
        buf = np.empty((size[1], size[0], 3), np.uint8)
        try:
            for i in range(first, len(plan.ticks), step):
                renderer.draw(int(plan.ticks[i]), plan.qpos[i], plan.lookat[i], out=buf, bgr=bgr)
                conn.send_bytes(buf.reshape(-1))  # flat: a Connection counts the first dimension only
        finally:
            renderer.close()
    except (BrokenPipeError, KeyboardInterrupt):  # the encoder stopped
        pass
    except Exception as exc:
        msg = str(exc) if isinstance(exc, WbcError) else f"{type(exc).__name__}: {exc}"
        try:
            conn.send_bytes(b"E" + msg.encode()[:4000])
        except OSError:
            pass
    finally:
        conn.close()


class _Frames:
    """The frames of a plan, in order: rendered inline (1 worker) or by worker processes with interleaved frames.

    Each frame is a view of one of `buffers` pixel buffers (`_Renderer.draw`), handed out again once given back
    with `release`: a consumer in another thread holds at most `buffers` frames, and iterating waits for one to
    be given back; with 1 buffer and no `release`, each frame is overwritten by the next.
    """

    def __init__(self, replay: Replay, plan: _FramePlan, size: tuple[int, int], camera: str, overlays: Overlays,
                 workers: int, bgr: bool = False, buffers: int = 1):
        import queue

        self.n = len(plan.ticks)
        self.workers = max(1, min(int(workers), self.n))
        self.size = size
        self.bgr = bgr
        self.free: queue.Queue = queue.Queue()
        for _ in range(max(1, buffers)):
            self.free.put(np.empty((size[1], size[0], 3), np.uint8))
        self.pooled = buffers > 1
        self.procs, self.conns, self.renderer, self.tmp = [], [], None, None
        if self.workers == 1:
            self.renderer = _Renderer(replay, size[0], size[1], camera, overlays)
            self.plan = plan
            return
        import multiprocessing as mp
        import tempfile

        import mujoco

        # the model once to a file (its collision BVHs make it ~30 MB: pickling it per process costs more)
        self.tmp = tempfile.TemporaryDirectory(prefix="wbcbench-render-")
        model_file = str(Path(self.tmp.name) / "model.mjb")
        mujoco.mj_saveModel(replay.model, model_file, None)
        state = replay.worker_state()
        ctx = mp.get_context("spawn")  # a fresh process: its own OpenGL context, no inherited threads
        for w in range(self.workers):
            recv, send = ctx.Pipe(duplex=False)
            p = ctx.Process(target=_render_worker, daemon=True,
                            args=(state, model_file, plan, w, self.workers, size, camera, overlays, bgr, send))
            p.start()
            send.close()
            self.procs.append(p)
            self.conns.append(recv)

    def release(self, img: np.ndarray) -> None:
        """Give back a frame's buffer (the frame must not be used after)."""
        self.free.put(img.base if img.base is not None else img)

    def _buffer(self) -> np.ndarray:
        buf = self.free.get()
        if not self.pooled:
            self.free.put(buf)
        return buf

    def __iter__(self):
        if self.renderer is not None:
            p = self.plan
            for i in range(self.n):
                yield self.renderer.draw(int(p.ticks[i]), p.qpos[i], p.lookat[i], out=self._buffer(), bgr=self.bgr)
            return
        for i in range(self.n):
            w = i % self.workers
            buf = self._buffer()
            try:
                got = self.conns[w].recv_bytes_into(buf.reshape(-1))
            except EOFError:
                raise RenderError(f"render process {w} ended before frame {i} "
                                  f"(exit code {self.procs[w].exitcode})") from None
            if got != buf.nbytes:
                raise RenderError(bytes(buf.reshape(-1)[1:got]).decode(errors="replace"))
            yield buf[::-1]

    def close(self) -> None:
        if self.renderer is not None:
            self.renderer.close()
        for c in self.conns:
            c.close()
        for p in self.procs:
            p.join(timeout=5)
            if p.is_alive():
                p.terminate()
                p.join()
        if self.tmp is not None:
            self.tmp.cleanup()


class _Encoder:
    """H.264 encoding of frames in a thread of its own, so that drawing the next frame (in MuJoCo and Mesa, which
    release Python's lock) and encoding this one (PyAV's BGR to YUV conversion and x264, which release it too)
    run at once on two cores. Each frame's buffer is given back to `frames` once encoded."""

    def __init__(self, stream, container, frames: _Frames, threaded: bool):
        import queue
        import threading

        self.stream, self.container, self.frames = stream, container, frames
        self.error: BaseException | None = None
        self.thread = None
        if threaded:
            self.todo: queue.Queue = queue.Queue()
            self.thread = threading.Thread(target=self._run, name="wbcbench-encoder", daemon=True)
            self.thread.start()

    def _encode(self, img: np.ndarray | None) -> None:
        import av

        frame = None if img is None else av.VideoFrame.from_ndarray(img, format="bgr24" if self.frames.bgr
                                                                    else "rgb24")
        if img is not None:
            self.frames.release(img)
        for packet in self.stream.encode(frame):
            self.container.mux(packet)

    def _run(self) -> None:
        while True:
            img = self.todo.get()
            try:
                if self.error is None:
                    self._encode(img)
            except BaseException as exc:  # kept for the drawing thread, which raises it
                self.error = exc
            if img is None:
                return
            if self.error is not None:
                self.frames.release(img)  # the drawing thread may be waiting for a buffer

    def put(self, img: np.ndarray) -> None:
        """Encode `img` (a frame of `frames`), now or in the thread."""
        if self.error is not None:
            raise self.error
        if self.thread is None:
            self._encode(img)
        else:
            self.todo.put(img)

    def stop(self) -> None:
        """End the thread without encoding what is left (drawing failed or was interrupted)."""
        if self.thread is not None:
            if self.error is None:
                self.error = RenderError("stopped")
            self.todo.put(None)
            self.thread.join()

    def finish(self) -> None:
        """Flush the encoder (waits for the thread): raises the thread's error, if any."""
        if self.thread is None:
            self._encode(None)
            return
        self.todo.put(None)
        self.thread.join()
        if self.error is not None:
            raise self.error


def render_run(run_dir: str | Path, out: str | Path | None = None, *, size: str | tuple[int, int] = "1280x720",
               fps: float = 30.0, speed: float = 1.0, camera: str = "follow", overlays: Overlays = Overlays(),
               progress: Callable[[float], None] | None = None, workers: int = 1,
               mesh_cell: float = MESH_CELL_M, preset: str = "ultrafast", threaded: bool = True) -> Path:
    """Render a run directory to an H.264 MP4 (default RUN_DIR/video.mp4); returns its path.

    `speed`: playback speed (0.5: slow motion); `fps`: frames per second of the video; a frame shows the last
    logged state at or before its time. `workers`: render processes feeding one H.264 encoder here (x264
    `preset`); 1 (default) renders in this process, which already uses every core (Mesa's llvmpipe rasterizes and
    x264 encodes in threads): on 2 shared cores, 2 processes cost 40 % more CPU per frame and were not faster
    (benchmarks/bench_render.py). `threaded`: encode in a thread of its own while the next frame is drawn
    (`_Encoder`); False encodes each frame before drawing the next. `mesh_cell`: grid cell [m] of the visual meshes'
    simplification, 0 for the full meshes.

    Raises:
        ConfigError: not a run directory, an unreadable log, bad size / fps / speed / camera / workers.
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
    workers = int(workers)
    if workers < 1:
        raise ConfigError(f"workers must be >= 1, got {workers}", key="--workers")
    replay = _render_replay(run_dir, mesh_cell)
    out = Path(out) if out is not None else run_dir / "video.mp4"
    n = int(np.floor(replay.duration / speed * fps + 1e-9)) + 1
    plan = _plan(replay, np.arange(n) * speed / fps, camera)
    # 3 buffers: the frame being drawn, the one being encoded, one waiting between them
    frames = _Frames(replay, plan, (w, h), camera, overlays, workers, bgr=True, buffers=3 if threaded else 1)
    try:
        try:
            container = av.open(str(out), mode="w")
        except OSError as exc:
            raise ConfigError(f"cannot write the video ({exc.strerror or exc})", file=str(out)) from None
        try:
            stream = container.add_stream("libx264" if "libx264" in av.codecs_available else "h264",
                                          rate=int(round(fps)))
            stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
            stream.options = {"crf": "23", "preset": preset}
            encoder = _Encoder(stream, container, frames, threaded)
            try:
                for i, img in enumerate(frames):
                    encoder.put(img)
                    if progress is not None and i % 10 == 0:
                        progress((i + 1) / n)
            except BaseException:
                encoder.stop()
                raise
            encoder.finish()
        finally:
            container.close()
    finally:
        frames.close()
    if progress is not None:
        progress(1.0)
    return out


def keyframe_strip(run_dir: str | Path, out: str | Path | None = None, *, frames: int = 6,
                   size: str | tuple[int, int] = "320x400", camera: str = "follow",
                   overlays: Overlays = Overlays(caption=False), mesh_cell: float = MESH_CELL_M) -> Path:
    """A PNG of `frames` frames of the run side by side, evenly spread over it (default RUN_DIR/keyframes.png).

    The follow camera is where it would be in a 30 frames/s video at those times (its path is computed, only the
    key frames are rendered)."""
    from PIL import Image

    run_dir = Path(run_dir)
    w, h = _size(size)
    if frames < 1:
        raise ConfigError(f"the number of key frames must be >= 1, got {frames}", key="--keyframes")
    replay = _render_replay(run_dir, mesh_cell)
    video = np.arange(0.0, replay.duration + 1e-9, 1.0 / 30.0)
    plan = _plan(replay, video, camera)
    # the video frame at or just before each key time (the last frame for the end of the run)
    picks = np.minimum(np.searchsorted(video, np.linspace(0.0, replay.duration, frames) + 1e-9) - 1, len(video) - 1)
    renderer = _Renderer(replay, w, h, camera, overlays)
    try:
        imgs = [renderer.draw(int(plan.ticks[i]), plan.qpos[i], plan.lookat[i]) for i in picks]
    finally:
        renderer.close()
    out = Path(out) if out is not None else run_dir / "keyframes.png"
    Image.fromarray(np.hstack(imgs)).save(out)
    return out
