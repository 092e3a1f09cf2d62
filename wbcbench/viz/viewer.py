"""Browser replay of run directories with viser: `wbcbench view RUN_DIR [RUN_DIR ...]`.

Each run is read by `replay.Replay` (only its directory: config.json + log.parquet). The robots' visual meshes and
the terrain are sent to the browser once; a frame only moves each robot's body frames and the overlay markers.
Several runs share one timeline and are shown overlaid (the first opaque, the others as tinted ghosts) or side by
side (offset in y). Overlays, each a toggle: planned footholds, CoM and its reference, planned and measured ZMP,
contact forces (arrows, 1 m per 1000 N, from each foot's centre of pressure), support polygon, frame-task targets
(teleoperation: the operator's retargeted hands and head, as axes), caption (a label over each robot and the time
in the panel). Two time plots of a chosen log channel per run, with a vertical cursor at the timeline's time.

The server binds 127.0.0.1 unless another host is given; the port must be free (no silent move to the next).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .replay import FORCE_THRESHOLD, Replay, cop
from .scene3d import RobotNodes, add_terrain, disc_mesh, move, start_server, stop_server

__all__ = ["LAYOUTS", "PLOTS", "ReplayViewer"]

LAYOUTS = ("ghost", "side")
#: opacity of the runs after the first in the ghost layout
GHOST_OPACITY = 0.4
#: [m] distance between neighbouring runs in the side-by-side layout
SIDE_SPACING = 1.5
#: run colours: ghost tints, labels and plot series (the first run keeps its own colours in the scene)
PALETTE = ((230, 120, 20), (40, 110, 240), (30, 170, 80), (200, 50, 170), (120, 120, 120), (20, 170, 190))
SPEEDS = ("0.1", "0.25", "0.5", "1", "2", "4")
#: display rate of the playback [frames per wall-clock second]
PLAY_RATE = 30.0
#: points per series in the time plots (runs are resampled to this many)
PLOT_POINTS = 600
#: the preset time plots: title -> [(channel, component, series label)]
PLOTS = {
    "CoM y and reference [m]": [("com", 1, "CoM"), ("com_ref", 1, "ref")],
    "CoM x and reference [m]": [("com", 0, "CoM"), ("com_ref", 0, "ref")],
    "CoM height [m]": [("com", 2, "CoM")],
    "ZMP x planned / measured [m]": [("zmp_ref", 0, "planned"), ("measured_zmp", 0, "measured")],
    "ZMP y planned / measured [m]": [("zmp_ref", 1, "planned"), ("measured_zmp", 1, "measured")],
    "contact force z left / right [N]": [("contact_left", 2, "left"), ("contact_right", 2, "right")],
    "controller step time [us]": [("controller_time_us", 0, "step")],
}
_MAX_POLYGON = 8  # support polygon corners sent per frame (a hull of two soles has at most 8)


class ReplayViewer:
    """A viser server replaying run directories; `show(t)` sets every run to time t [s].

    Raises:
        ConfigError: a bad run directory (replay.Replay), an unknown layout, a port in use.
    """

    def __init__(self, run_dirs: Sequence[str | Path], *, host: str = "127.0.0.1", port: int = 8080,
                 layout: str = "ghost"):
        import mujoco

        if not run_dirs:
            raise ConfigError("give at least one run directory", key="RUN_DIR")
        if layout not in LAYOUTS:
            raise ConfigError(f"unknown layout '{layout}'; allowed: {', '.join(LAYOUTS)}", key="--layout")
        self.replays = [Replay(d) for d in run_dirs]  # every directory checked before a port is taken
        self.duration = max(r.duration for r in self.replays)
        self._datas = [mujoco.MjData(r.model) for r in self.replays]
        self._mj = mujoco
        self.server = start_server(host, port, "wbcbench replay")
        self.host, self.port = host, port
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self.time = 0.0
        self._last_plot = 0.0
        try:
            self._build_scene()
            self._build_gui(layout)
            self.set_layout(layout)
            self.show(0.0)
        except BaseException:
            stop_server(self.server)
            raise
        self._player = threading.Thread(target=self._play_loop, name="wbcbench-replay", daemon=True)
        self._player.start()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    # ------------------------------------------------------------------ scene
    def _build_scene(self) -> None:
        from ..recorder import channel

        scene = self.server.scene
        self.roots, self.robots, self.terrains, self.marks = [], [], [], []
        disc_v, disc_f = disc_mesh(0.06)
        for i, rp in enumerate(self.replays):
            root = f"/run{i}"
            self.roots.append(scene.add_frame(root, show_axes=False))
            self.terrains.append(scene.add_frame(f"{root}/terrain", show_axes=False))
            add_terrain(scene, f"{root}/terrain", rp.model)
            m = {"robot": scene.add_frame(f"{root}/robot", show_axes=False)}  # the robot's toggle
            self.robots.append(RobotNodes(scene, f"{root}/robot", rp.model))
            color = PALETTE[i % len(PALETTE)]
            f = rp.footholds
            m["footholds"] = scene.add_batched_meshes_simple(
                f"{root}/footholds", disc_v, disc_f, np.tile([1.0, 0, 0, 0], (max(len(f), 1), 1)),
                (f + [0, 0, 0.003]) if len(f) else np.zeros((1, 3)), batched_colors=(50, 200, 50), opacity=0.6,
                cast_shadow=False, receive_shadow=False, visible=bool(len(f)))
            m["com"] = scene.add_icosphere(f"{root}/com", 0.025, color=(255, 128, 0), cast_shadow=False)
            m["com_ref"] = scene.add_icosphere(f"{root}/com_ref", 0.025, color=(255, 255, 255), cast_shadow=False)
            m["zmp_ref"] = scene.add_box(f"{root}/zmp_ref", dimensions=(0.04, 0.04, 0.008), color=(50, 100, 255),
                                         cast_shadow=False)
            m["zmp"] = scene.add_box(f"{root}/zmp", dimensions=(0.04, 0.04, 0.008), color=(255, 25, 25),
                                     cast_shadow=False)
            for side in ("left", "right"):
                m[f"force_{side}"] = scene.add_arrows(f"{root}/force_{side}", np.zeros((1, 2, 3)) + [[0, 0, 0],
                                                      [0, 0, 0.1]], (255, 230, 25), shaft_radius=0.008,
                                                      head_radius=0.02, head_length=0.05)
            m["support"] = scene.add_line_segments(f"{root}/support", np.zeros((_MAX_POLYGON, 2, 3)),
                                                   (0, 170, 255), thickness=0.01)
            m["targets"] = {}  # frame-task targets (teleoperation: the operator's hands and head), as axes
            for name in sorted({c[len("target_"):].split(".")[0] for c in rp.log if c.startswith("target_")}):
                m["targets"][name] = (scene.add_frame(f"{root}/targets/{name}", axes_length=0.12, axes_radius=0.008),
                                      channel(rp.log, f"target_{name}"))
            m["label"] = scene.add_label(f"{root}/label", rp.config.get("controller", f"run {i}"),
                                         anchor="bottom-center")
            m["color"] = color
            self.marks.append(m)

    def set_layout(self, layout: str) -> None:
        """'ghost': all runs at their own place, those after the first translucent and tinted; 'side': one beside
        the other along y, all opaque."""
        with self._lock:
            n = len(self.replays)
            for i, (root, robot, terrain) in enumerate(zip(self.roots, self.robots, self.terrains)):
                if layout == "side":
                    root.position = (0.0, (i - (n - 1) / 2) * SIDE_SPACING, 0.0)
                    robot.style(None, None)
                    terrain.visible = True
                else:
                    root.position = (0.0, 0.0, 0.0)
                    robot.style(GHOST_OPACITY if i else None, PALETTE[i % len(PALETTE)] if i else None)
                    terrain.visible = i == 0
            self.layout = layout
            base = np.mean([r.q[0, :3] for r in self.replays], axis=0)
            spread = 0.0 if layout == "ghost" else (n - 1) * SIDE_SPACING
            cam = self.server.initial_camera
            # the robots left of the image's centre (the panel covers the right of it): the look-at point moved
            # along the image's horizontal, (1, 1, 0) from this camera
            aim = base + [0.45, 0.45, 0.0]
            cam.look_at = (aim[0], aim[1], 0.7)
            cam.position = (aim[0] + 2.2 + 0.4 * spread, aim[1] - 2.2 - 0.6 * spread, 1.5)

    # ------------------------------------------------------------------ GUI
    def _build_gui(self, layout: str) -> None:
        gui = self.server.gui
        step = min(float(r.config.get("control_dt_s") or 0.002) for r in self.replays)
        self.caption = gui.add_markdown(self._caption_text(0.0))
        self.slider = gui.add_slider("time [s]", 0.0, round(self.duration, 6), step, 0.0)
        self.play_button = gui.add_button("Play")
        self.speed = gui.add_dropdown("speed", SPEEDS, initial_value="1")
        self.layout_menu = gui.add_dropdown("layout", LAYOUTS, initial_value=layout,
                                            disabled=len(self.replays) < 2)
        self.playing = False

        @self.slider.on_update
        def _(_event) -> None:
            self.show(float(self.slider.value))

        @self.play_button.on_click
        def _(_event) -> None:
            self.set_playing(not self.playing)

        @self.layout_menu.on_update
        def _(_event) -> None:
            self.set_layout(self.layout_menu.value)

        with gui.add_folder("overlays"):
            self.toggles = {name: gui.add_checkbox(name, True) for name in
                            ("robots", "footholds", "CoM", "ZMP", "contact forces", "support polygon", "targets",
                             "caption")}
        for box in self.toggles.values():
            box.on_update(lambda _event: self.show(self.time))
        self._columns = sorted({c for r in self.replays for c in r.log if c != "t"})
        choices = list(PLOTS) + [f"log: {c}" for c in self._columns]
        self.plots = []
        for k, initial in enumerate(("CoM y and reference [m]", "contact force z left / right [N]")):
            with gui.add_folder(f"plot {k + 1}"):
                menu = gui.add_dropdown("channel", choices, initial_value=initial)
                x, series, labels = self._plot_data(initial)
                data, series_opts, scales = self._uplot_args(x, series, labels, 0.0)
                handle = gui.add_uplot(data, series_opts, scales=scales, aspect=1.5)
            plot = {"menu": menu, "handle": handle, "x": x, "series": series, "labels": labels}
            self.plots.append(plot)

            def changed(_event, plot=plot) -> None:
                plot["x"], plot["series"], plot["labels"] = self._plot_data(plot["menu"].value)
                data, series_opts, _ = self._uplot_args(plot["x"], plot["series"], plot["labels"], self.time)
                plot["handle"].series = series_opts
                plot["handle"].scales = self._scales(plot["series"])
                plot["handle"].data = data

            menu.on_update(changed)

    def _caption_text(self, t: float) -> str:
        rows = [f"**t = {t:6.3f} s** of {self.duration:.3f} s"]
        for i, rp in enumerate(self.replays):
            r, g, b = PALETTE[i % len(PALETTE)]
            rows.append(f"<span style='color:rgb({r},{g},{b})'>&#9632;</span> run {i}: {rp.label}"
                        + (" (ghost)" if i and self.__dict__.get("layout") == "ghost" else ""))
        return "  \n".join(rows)

    # ------------------------------------------------------------------ plots
    def _series(self, rp: Replay, channel: str, comp: int) -> np.ndarray | None:
        if channel == "measured_zmp":
            return None if rp.measured_zmp is None else rp.measured_zmp[:, comp]
        if channel in rp.channels:
            c = rp.channels[channel]
            return None if c is None else c[:, comp]
        return np.asarray(rp.log[channel], dtype=float) if channel in rp.log else None

    def _plot_data(self, choice: str):
        """(x (PLOT_POINTS,), [series (PLOT_POINTS,)], [labels]) of a plot choice, every run sampled on one grid
        (the last logged value at or before each time; NaN past a run's end)."""
        x = np.linspace(0.0, self.duration, PLOT_POINTS)
        spec = PLOTS.get(choice) or [(choice.removeprefix("log: "), 0, choice.removeprefix("log: "))]
        series, labels = [], []
        for i, rp in enumerate(self.replays):
            ticks = np.minimum(np.searchsorted(rp.t, x - 1e-9), len(rp.t) - 1)
            past = x > rp.duration + 1e-9
            for channel, comp, label in spec:
                y = self._series(rp, channel, comp)
                if y is None:
                    continue
                s = y[ticks].astype(float)
                s[past] = np.nan
                series.append(s)
                labels.append((i, f"{i}: {label}" if len(self.replays) > 1 else label))
        return x, series, labels

    @staticmethod
    def _range(series) -> tuple[float, float]:
        vals = np.concatenate([s[np.isfinite(s)] for s in series]) if series else np.zeros(0)
        if vals.size == 0:
            return -1.0, 1.0
        lo, hi = float(vals.min()), float(vals.max())
        pad = 0.05 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.05
        return lo - pad, hi + pad

    def _scales(self, series) -> dict:
        lo, hi = self._range(series)
        return {"x": {"time": False}, "y": {"range": [lo, hi]}}

    def _uplot_args(self, x, series, labels, t: float):
        """uPlot data with a vertical cursor at t: two points (t, low) and (t, high) of a 'now' series inserted in
        the time axis (NaN elsewhere; the other series take their value there)."""
        lo, hi = self._range(series)
        j = int(np.searchsorted(x, t))
        xs = np.insert(x, j, [t, t])
        cols = [xs]
        for s in series:
            v = s[min(j, len(s) - 1)] if j < len(s) else s[-1]
            cols.append(np.insert(s, j, [v, v]))
        now = np.full(len(xs), np.nan)
        now[j], now[j + 1] = lo, hi
        cols.append(now)
        opts = [{"label": "t [s]"}]
        dash = ([], [6, 4], [2, 3])
        per_run: dict[int, int] = {}
        for run, label in labels:
            r, g, b = PALETTE[run % len(PALETTE)]
            n = per_run.get(run, 0)
            per_run[run] = n + 1
            opts.append({"label": label, "stroke": f"rgb({r},{g},{b})", "width": 1.5, "dash": dash[n % 3]})
        opts.append({"label": "now", "stroke": "rgb(0,0,0)", "width": 1.5})
        return tuple(cols), tuple(opts), self._scales(series)

    def _update_plots(self, t: float) -> None:
        for plot in self.plots:
            data, _, _ = self._uplot_args(plot["x"], plot["series"], plot["labels"], t)
            plot["handle"].data = data

    # ------------------------------------------------------------------ frames
    def show(self, t: float) -> None:
        """Every run at time t [s] (the last logged state at or before t), the overlays and the plot cursors."""
        mj = self._mj
        t = float(np.clip(t, 0.0, self.duration))
        if abs(float(self.slider.value) - t) > 1e-9:  # called from code: the slider moves, and its callback shows
            self.slider.value = t
            return
        with self._lock, self.server.atomic():
            self.time = t
            on = {name: box.value for name, box in self.toggles.items()}
            for rp, data, robot, m in zip(self.replays, self._datas, self.robots, self.marks):
                k = rp.tick_at(t)
                rp.bridge.q_to_mj(rp.q[k], data.qpos)
                mj.mj_kinematics(rp.model, data)
                robot.set(data)
                self._overlays(rp, k, m, on)
            self.caption.content = self._caption_text(t)
            now = time.perf_counter()
            if not self.playing or now - self._last_plot > 0.1:  # the cursors at 10 Hz while playing
                self._update_plots(t)
                self._last_plot = now

    def _overlays(self, rp: Replay, k: int, m: dict, on: dict) -> None:
        ch = rp.channels
        m["robot"].visible = on["robots"]
        m["footholds"].visible = on["footholds"] and len(rp.footholds) > 0
        for name in ("com", "com_ref"):
            c = ch.get(name)
            ok = on["CoM"] and c is not None and np.isfinite(c[k]).all()
            m[name].visible = ok
            if ok:
                move(m[name], (c[k, 0], c[k, 1], 0.02))
        z = ch.get("zmp_ref")
        ok = on["ZMP"] and z is not None and np.isfinite(z[k]).all()
        m["zmp_ref"].visible = ok
        if ok:
            move(m["zmp_ref"], z[k] + [0, 0, 0.006])
        zm = rp.measured_zmp[k] if rp.measured_zmp is not None else None
        ok = on["ZMP"] and zm is not None and np.isfinite(zm).all()
        m["zmp"].visible = ok
        if ok:
            move(m["zmp"], zm + [0, 0, 0.006])
        for side in ("left", "right"):
            w = ch.get(f"contact_{side}")
            ok = on["contact forces"] and w is not None and np.isfinite(w[k]).all() and w[k, 2] >= FORCE_THRESHOLD
            m[f"force_{side}"].visible = ok
            if ok:
                p = cop(w[k, :3], w[k, 3:])
                m[f"force_{side}"].points = np.array([[p, p + w[k, :3] / 1000.0]])  # 1 m per 1000 N
        hull = rp.support_polygon(k) if on["support polygon"] else np.zeros((0, 2))
        m["support"].visible = len(hull) > 0
        if len(hull):
            pts = np.zeros((_MAX_POLYGON, 2, 3))
            n = min(len(hull), _MAX_POLYGON)
            ring = np.column_stack([hull[:n], np.full(n, 0.004)])
            pts[:n, 0], pts[:n, 1] = ring, np.roll(ring, -1, axis=0)
            pts[n:] = ring[-1]  # unused segments: zero length
            m["support"].points = pts
        for frame, T in m["targets"].values():  # position (3), rotation matrix row-major (9)
            ok = on["targets"] and np.isfinite(T[k, :3]).all()
            frame.visible = ok
            if ok:
                move(frame, T[k, :3])
                if np.isfinite(T[k, 3:]).all():
                    wxyz = np.zeros(4)
                    self._mj.mju_mat2Quat(wxyz, T[k, 3:])
                    frame.wxyz = wxyz
        m["label"].visible = on["caption"]
        if on["caption"]:
            move(m["label"], rp.q[k, :3] + [0, 0, 0.75])

    # ------------------------------------------------------------------ playback
    def set_playing(self, playing: bool) -> None:
        with self._lock:
            if playing and self.time >= self.duration - 1e-9:
                self.slider.value = 0.0
            self.playing = playing
            self.play_button.label = "Pause" if playing else "Play"
            if not playing:
                self._update_plots(self.time)

    def _play_loop(self) -> None:
        last = time.perf_counter()
        while not self._stop.wait(1.0 / PLAY_RATE):
            now = time.perf_counter()
            dt, last = now - last, now
            if not self.playing:
                continue
            t = self.time + dt * float(self.speed.value)
            if t >= self.duration:
                t = self.duration
                self.slider.value = t
                self.set_playing(False)
            else:
                self.slider.value = t

    def close(self) -> None:
        """Stop the playback thread and the server (idempotent)."""
        if not self._stop.is_set():
            self._stop.set()
            self._player.join(timeout=2.0)
            stop_server(self.server)

    def __enter__(self) -> "ReplayViewer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
