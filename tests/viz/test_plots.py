"""PNG plots: written, non-empty, with content (not a blank canvas)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from viz import write_plots
from viz.plots import skeleton_segments


@pytest.fixture(scope="module")
def plots(tmp_path_factory, talos, synth_plan, synth_execution):
    out = tmp_path_factory.mktemp("plots")
    return out, write_plots(out / "nested" / "dir", talos, synth_plan, execution=synth_execution)


def test_all_plots_written_with_content(plots):
    out, paths = plots
    names = [p.name for p in paths]
    assert names == ["com_support.png", "joints.png", "torques.png", "contact_forces.png", "keyframes.png"]
    for p in paths:
        assert p.is_file() and p.stat().st_size > 20_000, p
        px = np.asarray(Image.open(p).convert("L"), dtype=float)
        assert px.shape[0] > 300 and px.shape[1] > 600
        assert px.std() > 15.0, f"{p.name} looks blank (pixel std {px.std():.1f})"
        assert np.mean(px < 128) > 0.005, f"{p.name} has almost no dark ink"
    leftovers = [x.name for x in paths[0].parent.iterdir() if x.suffix != ".png" or x.name.startswith(".")]
    assert leftovers == []


def test_plan_only_kinematic_skips_torques_and_forces(tmp_path, talos, synth_plan):
    paths = write_plots(tmp_path, talos, synth_plan)
    assert [p.name for p in paths] == ["com_support.png", "joints.png", "keyframes.png"]


def test_skeleton_spans_the_robot(talos):
    segs = skeleton_segments(talos, talos.q_standing)
    assert segs.shape[1:] == (2, 3)
    z = segs[:, :, 2]
    assert z.min() == pytest.approx(0.0, abs=1e-6)  # the sole frames are on the ground
    assert z.max() > 0.7 * talos.height()
