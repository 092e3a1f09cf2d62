"""Model error: the simulated robot differs from the controller's model (paper 000 met an unmodelled hip
flexibility and payloads on the real TALOS). Applied to the compiled MuJoCo model only; the controller keeps
the nominal pinocchio model.

    model_error:                      # a scenario section, or --model-error FILE.yaml
      mass_error: 0.1                 # each link's mass (and inertia) scaled by 1 + U(-0.1, 0.1)
      com_offset: 0.01                # [m] each link's centre of mass moved by U(-0.01, 0.01) per axis
      payloads:                       # rigid point masses fixed to links (link frame offset [m])
        - {link: torso_2_link, mass: 10.0, offset: [-0.3, 0.0, 0.1]}
      friction: 0.4                   # sliding friction of soles, floor and terrain (MuJoCo takes the max of a pair)
      ground_timeconst: 0.05          # [s] floor contact time constant (default 0.02): softer ground
      seed: 0                         # the random draws above
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..config import Section
from ..errors import UnknownNameError

__all__ = ["ModelError", "Payload", "apply_model_error", "parse_model_error"]


@dataclass(frozen=True)
class Payload:
    """A point mass [kg] fixed to `link` at `offset` [m] (link frame, from the link origin)."""

    link: str
    mass: float
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ModelError:
    """See the module docstring. All zero / None: the simulated robot is the model."""

    mass_error: float = 0.0
    com_offset: float = 0.0
    payloads: tuple[Payload, ...] = field(default_factory=tuple)
    friction: float | None = None
    ground_timeconst: float | None = None
    seed: int = 0

    @property
    def none(self) -> bool:
        return (not self.mass_error and not self.com_offset and not self.payloads and self.friction is None
                and self.ground_timeconst is None)


def parse_model_error(sec: Section) -> ModelError:
    payloads = []
    for i, raw in enumerate(sec.list("payloads", [])):
        p = Section(raw, sec.file, f"{sec.key('payloads')}[{i}]")
        payloads.append(Payload(link=p.str("link"), mass=p.float("mass", positive=True),
                                offset=tuple(p.vector("offset", [0.0, 0.0, 0.0], length=3))))
        p.finish()
    err = ModelError(mass_error=sec.float("mass_error", 0.0, min=0.0, max=0.9),
                     com_offset=sec.float("com_offset", 0.0, min=0.0, max=0.5), payloads=tuple(payloads),
                     friction=sec.float("friction", positive=True) if sec.has("friction") else None,
                     ground_timeconst=(sec.float("ground_timeconst", positive=True)
                                       if sec.has("ground_timeconst") else None),
                     seed=sec.int("seed", 0, min=0))
    sec.finish()
    return err


def _body(model: mujoco.MjModel, name: str, key: str) -> int:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid < 0:
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(1, model.nbody)]
        raise UnknownNameError("link (MuJoCo body)", name, names, key=key)
    return bid


def _inertia_matrix(model: mujoco.MjModel, b: int) -> np.ndarray:
    """The body's inertia about its CoM in body axes (3, 3)."""
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, model.body_iquat[b])
    R = R.reshape(3, 3)
    return R @ np.diag(model.body_inertia[b]) @ R.T


def _set_inertia(model: mujoco.MjModel, b: int, I: np.ndarray) -> None:
    w, V = np.linalg.eigh(0.5 * (I + I.T))
    if np.linalg.det(V) < 0:
        V[:, 0] = -V[:, 0]
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, V.reshape(-1))
    model.body_inertia[b] = np.maximum(w, 1e-9)
    model.body_iquat[b] = q


def apply_model_error(model: mujoco.MjModel, err: ModelError, floor_geoms: list[int]) -> dict:
    """Change the compiled `model` in place; returns what was changed (for config.json)."""
    if err.none:
        return {}
    rng = np.random.default_rng(err.seed)
    out: dict = {}
    robot_bodies = range(1, model.nbody)
    if err.mass_error:
        scale = 1.0 + rng.uniform(-err.mass_error, err.mass_error, model.nbody)
        for b in robot_bodies:
            model.body_mass[b] *= scale[b]
            model.body_inertia[b] *= scale[b]
        out["mass_scale"] = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b): float(scale[b])
                             for b in robot_bodies}
    if err.com_offset:
        for b in robot_bodies:
            model.body_ipos[b] += rng.uniform(-err.com_offset, err.com_offset, 3)
    for i, p in enumerate(err.payloads):
        b = _body(model, p.link, f"model_error.payloads[{i}].link")
        m, c = float(model.body_mass[b]), model.body_ipos[b].copy()
        r = np.asarray(p.offset, float)
        m2 = m + p.mass
        c2 = (m * c + p.mass * r) / m2
        I = _inertia_matrix(model, b)

        def shift(mass, d):
            return mass * (d @ d * np.eye(3) - np.outer(d, d))

        I2 = I + shift(m, c - c2) + shift(p.mass, r - c2)
        model.body_mass[b] = m2
        model.body_ipos[b] = c2
        _set_inertia(model, b, I2)
    if err.friction is not None:
        model.geom_friction[:, 0] = err.friction
    if err.ground_timeconst is not None:
        for g in floor_geoms:
            model.geom_solref[g, 0] = err.ground_timeconst
    data = mujoco.MjData(model)
    mujoco.mj_setConst(model, data)
    out["total_mass_kg"] = float(model.body_mass[1:].sum())
    return out
