"""``SimSettings.floor_timeconst``: a harder floor for the soles (the retarget's), the default untouched;
and what the option selects, measured on a free box of a sole's size resting on a floor in MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sim import SimSettings, build_model
from sim.exceptions import SimError
from sim.model import FLOOR


def test_the_floor_and_soles_get_the_time_constant_and_the_default_is_mujocos(g1):
    soft = build_model(g1).model
    hard = build_model(g1, floor_timeconst=0.005).model
    floor = mujoco.mj_name2id(hard, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)
    soles = [i for i in range(hard.ngeom) if (mujoco.mj_id2name(hard, mujoco.mjtObj.mjOBJ_GEOM, i) or "").endswith("_sole")]
    assert len(soles) == 2
    for g in (floor, *soles):
        np.testing.assert_allclose(hard.geom_solref[g], [0.005, 1.0])
        np.testing.assert_allclose(soft.geom_solref[g], [0.02, 1.0])  # MuJoCo's default


def test_too_stiff_for_the_timestep_is_refused():
    with pytest.raises(SimError, match="floor_timeconst"):
        SimSettings(floor_timeconst=0.0015)  # less than two 1 ms steps
    assert SimSettings().floor_timeconst is None


def _depth(timeconst: float) -> float:
    """How deep a 0.2 x 0.1 m box of 90 kg (talos's weight on one sole) rests in the floor after
    1 s at MuJoCo's 1 ms step, both geoms with ``solref (timeconst, 1)`` [m]."""
    xml = f"""<mujoco><option timestep="0.001" cone="elliptic"/>
      <worldbody><geom name="floor" type="plane" size="0 0 0.05" solref="{timeconst} 1"/>
        <body pos="0 0 0.02"><freejoint/>
          <geom type="box" size="0.1 0.05 0.01" mass="90" solref="{timeconst} 1"/></body>
      </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for _ in range(1000):
        mujoco.mj_step(model, data)
    return 0.01 - float(data.qpos[2])


def test_a_loaded_sole_sinks_less_on_the_harder_floor():
    """The resting depth goes as the time constant squared (MuJoCo's reference stiffness is
    1 / (d_max^2 timeconst^2)): 16 x shallower at 5 ms than at 20 ms (0.11 against 0.007 mm
    measured for a resting box; a robot's sole, loaded at its edge by the controller, sank 3.3
    and 0.4 mm)."""
    soft, hard = _depth(0.02), _depth(0.005)
    assert soft > 0 and hard > 0
    assert 10.0 < soft / hard < 25.0
