"""The look of renders (videos and key frames alike): a sky that fades from blue to white at the horizon and a
checker floor, drawn from the visual model only; the simulation's model has neither."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.runner import run
from wbcbench.viz.render import Overlays, _Renderer, _render_replay


@pytest.fixture(scope="module")
def stand_run(tmp_path_factory):
    return run("stand", "joint-pd", duration=0.2, out=tmp_path_factory.mktemp("r") / "stand").run_dir


def test_sky_gradient_and_checker_floor(stand_run):
    replay = _render_replay(stand_run)
    model = replay.model
    assert model.ntex == 2 and model.nmat >= 1  # the sky and the floor's checker
    r = _Renderer(replay, 320, 240, "side", Overlays.none())
    try:
        img = r.frame(0.1).astype(int)
    finally:
        r.close()
    top, bottom = img[:40], img[-60:]
    # the sky: blue above white, no black background
    assert top.min() > 60, "a black sky"
    assert (top[..., 2] - top[..., 0]).mean() > 15, "the sky is not blue at the top"
    # the floor: a checker, light and dark squares, light overall
    lum = bottom.mean(axis=2)
    assert lum.mean() > 120 and np.percentile(lum, 90) - np.percentile(lum, 10) > 15


def test_the_simulated_model_has_no_texture(talos):
    from wbcbench.scene import Terrain
    from wbcbench.sim.model import SimOptions, build_mujoco_model
    from wbcbench.types import ActuationMode

    sim = build_mujoco_model(talos, Terrain(), ActuationMode.TORQUE, SimOptions())
    assert sim.ntex == 0 and sim.nmat == 0 and (sim.geom_matid < 0).all()
