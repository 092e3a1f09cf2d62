"""The robot and the terrain of a MuJoCo model as viser scene nodes, for the replay viewer and the live view.

The robot is sent once: one frame node per body that carries visual meshes (`VISUAL_GROUP`), the body's meshes
below it at their fixed placement in the body frame. A frame then only moves the body frames (`RobotNodes.set`):
about 33 poses for TALOS, never a mesh again. The terrain is static: the floor plane and the boxes of the
model's world body.
"""

from __future__ import annotations

import contextlib
import io
import socket

import numpy as np
from viser._messages import SetOrientationMessage as _SetOrientation
from viser._messages import SetPositionMessage as _SetPosition

from ..errors import ConfigError

__all__ = ["RobotNodes", "add_terrain", "disc_mesh", "move", "start_server", "stop_server"]


def start_server(host: str, port: int, label: str, *, key: str = "--port"):
    """A viser server on exactly (host, port) (viser itself would move on to the next free port).

    Raises:
        ConfigError: the port is in use or cannot be bound on that host, or is out of range.
    """
    import viser

    if not 0 < int(port) < 65536:
        raise ConfigError(f"port {port} is out of range (1..65535)", key=key)
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except OSError as exc:
        raise ConfigError(f"unknown host '{host}' ({exc.strerror or exc})", key=key.replace("port", "host")) from None
    family, _, _, _, addr = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:  # the same options as the server's (asyncio's) bind
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(addr)
        except OSError as exc:
            raise ConfigError(f"cannot serve on {host}:{port}: {exc.strerror or exc} (give another with {key})",
                              key=key) from None
    with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner whatever its `verbose`
        server = viser.ViserServer(host=host, port=port, label=label, verbose=False)
    if server.get_port() != port:  # taken between the check and the server's bind
        stop_server(server)
        raise ConfigError(f"cannot serve on {host}:{port}: the port is in use (give another with {key})",
                          key=key)
    server.scene.set_up_direction("+z")
    # Plain lights: no shadow maps (each draws TALOS' 159,000 faces again per frame) and no environment map (its
    # filtering took 20 s before the first frame): software WebGL (a headless browser, a machine without a GPU)
    # pays both in seconds
    scene = server.scene
    scene.configure_default_lights(enabled=True, cast_shadow=False)
    scene.configure_environment_map(hdri=None)
    scene.add_light_ambient("/lights/ambient", color=(255, 255, 255), intensity=1.2)
    return server


def stop_server(server) -> None:
    """Stop a viser server and wait for its thread, without its "(viser) Server stopped" line on stdout."""
    with contextlib.redirect_stdout(io.StringIO()):
        server.stop()


def move(handle, position) -> None:
    """Set a scene node's position: the message viser's `handle.position = ...` sends, without its per-call
    validation and comparison (10 times slower: 130 us a call, the bulk of a frame's cost)."""
    p = tuple(float(x) for x in position)
    handle._impl.position[:] = p
    handle._impl.api._queue_scene_message(_SetPosition(handle._impl.name, p))


def _rgb(rgba: np.ndarray) -> tuple[int, int, int]:
    return tuple(int(round(255 * float(c))) for c in np.clip(rgba[:3], 0, 1))


def _tint(rgb: tuple[int, int, int], tint: tuple[int, int, int] | None, amount: float = 0.55):
    if tint is None:
        return rgb
    return tuple(int(round((1 - amount) * a + amount * b)) for a, b in zip(rgb, tint))


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise products of (n, 4) wxyz quaternions."""
    aw, ax, ay, az = a.T
    bw, bx, by, bz = b.T
    return np.column_stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])


class RobotNodes:
    """The robot's visual meshes of a MuJoCo model (built with `SimOptions(visuals=True)`) in a viser scene under
    `root`. `set(data)` moves them to the pose of an `MjData` after `mj_kinematics`.

    The body frames form the kinematic tree (`root/b1/b2/...`), each posed in its parent's frame: a frame sends
    the base's pose and one rotation per joint that turned; the positions of bodies on revolute joints never
    change, so they are not sent again. (Each pose is a message, and viser's handling of messages is most of the
    cost of a frame.)"""

    def __init__(self, scene, root: str, model, *, opacity: float | None = None,
                 tint: tuple[int, int, int] | None = None):
        from ..sim.model import VISUAL_GROUP

        self.root = root
        geoms = [g for g in range(model.ngeom) if model.geom_group[g] == VISUAL_GROUP and model.geom_dataid[g] >= 0]
        chain = set()
        for g in geoms:  # the visual bodies and every body between them and the world
            b = int(model.geom_bodyid[g])
            while b > 0 and b not in chain:
                chain.add(b)
                b = int(model.body_parentid[b])
        self.bodies = np.array(sorted(chain), dtype=int)  # MuJoCo numbers parents before their children
        self.parents = np.array([int(model.body_parentid[b]) for b in self.bodies], dtype=int)
        names = {0: root}
        for b, p in zip(self.bodies, self.parents):
            names[int(b)] = f"{names[int(p)]}/b{b}"
        self.frames = [scene.add_frame(names[int(b)], show_axes=False) for b in self.bodies]
        self._impls = [h._impl for h in self.frames]
        self._sent_pos = np.full((len(self.bodies), 3), np.inf)
        self._sent_quat = np.full((len(self.bodies), 4), np.inf)
        self.world_pos = np.full((len(self.bodies), 3), np.nan)  # as last set [m]
        self.meshes, self._colors = [], []
        for g in geoms:
            m = int(model.geom_dataid[g])
            v0, nv = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
            f0, nf = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
            color = _rgb(model.geom_rgba[g])
            self._colors.append(color)
            self.meshes.append(scene.add_mesh_simple(
                f"{names[int(model.geom_bodyid[g])]}/g{g}", model.mesh_vert[v0:v0 + nv],
                model.mesh_face[f0:f0 + nf], color=_tint(color, tint), opacity=opacity,
                position=model.geom_pos[g], wxyz=model.geom_quat[g], cast_shadow=False, receive_shadow=False))

    def set(self, data, *, tolerance: float = 1e-6) -> int:
        """Move the bodies to the pose of `data` (`xpos`, `xmat`, `xquat` after `mj_kinematics`); a body's
        position and orientation in its parent's frame are sent when they changed by more than `tolerance` [m,
        and about rad / 2 for the orientation] since last sent. Returns the number of poses sent."""
        b, p = self.bodies, self.parents
        R = data.xmat[p].reshape(-1, 3, 3)
        pos = np.einsum("nji,nj->ni", R, data.xpos[b] - data.xpos[p])  # R_parent^T (x_body - x_parent)
        conj = data.xquat[p] * [1.0, -1.0, -1.0, -1.0]
        quat = _quat_mul(conj, data.xquat[b])
        self.world_pos[:] = data.xpos[b]
        send_pos = np.flatnonzero((np.abs(pos - self._sent_pos) > tolerance).any(axis=1))
        send_quat = np.flatnonzero((np.abs(quat - self._sent_quat) > tolerance).any(axis=1))
        self._sent_pos[send_pos], self._sent_quat[send_quat] = pos[send_pos], quat[send_quat]
        impls = self._impls
        for i, v in zip(send_pos, pos[send_pos].tolist()):  # the messages of `h.position = v` (see `move`)
            impls[i].position[:] = v
            impls[i].api._queue_scene_message(_SetPosition(impls[i].name, tuple(v)))
        for i, v in zip(send_quat, quat[send_quat].tolist()):  # and of `h.wxyz = v`
            impls[i].wxyz[:] = v
            impls[i].api._queue_scene_message(_SetOrientation(impls[i].name, tuple(v)))
        return len(send_pos) + len(send_quat)

    def style(self, opacity: float | None, tint: tuple[int, int, int] | None) -> None:
        """Change the meshes' opacity (None: opaque) and colour tint (e.g. ghosts)."""
        for h, c in zip(self.meshes, self._colors):
            h.opacity = opacity
            h.color = _tint(c, tint)


def add_terrain(scene, root: str, model, *, floor_size: float = 30.0) -> list:
    """The floor plane (a thin slab under z = 0 and a grid) and the boxes of the model's world body; returns
    the handles."""
    import mujoco

    out = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != 0:
            continue
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            z = float(model.geom_pos[g][2])
            out.append(scene.add_box(f"{root}/floor", dimensions=(floor_size, floor_size, 0.01),
                                     color=(205, 205, 196), position=(0.0, 0.0, z - 0.0051), cast_shadow=False))
            out.append(scene.add_grid(f"{root}/grid", floor_size, floor_size, cell_size=0.25, section_size=1.0,
                                      position=(0.0, 0.0, z + 0.001), cell_color=(150, 150, 142),
                                      section_color=(110, 110, 100)))
        elif model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            out.append(scene.add_box(f"{root}/box{g}", dimensions=tuple(2 * model.geom_size[g]),
                                     color=(166, 140, 115), position=model.geom_pos[g], wxyz=model.geom_quat[g]))
    return out


def disc_mesh(radius: float, segments: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A flat disc in the xy plane facing +z: (vertices (n + 1, 3), faces (n, 3))."""
    a = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    v = np.vstack([[0.0, 0.0, 0.0], np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros(segments)])])
    i = np.arange(segments)
    return v, np.column_stack([np.zeros(segments, int), 1 + i, 1 + (i + 1) % segments])
