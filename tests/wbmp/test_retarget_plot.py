"""``wbmp retarget --plot``: a PNG of the scaled source keypoints against the robot's, whose data
are the report's figures (its largest error is the reported max) and the robot's keypoints
Pinocchio's forward kinematics of the motion."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from wbmp.cli import main

ROOT = Path(__file__).resolve().parents[2]
DANCE = ROOT / "examples" / "motions" / "18_15_dance.bvh"
WINDOW = ("--start", "0", "--end", "0.6")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The dance's first 0.6 s on talos, planned (no simulation) with ``--plot DIR/``; then the
    same request answered from the motion cache as a RetargetResult."""

    from wbmp.retarget import RetargetRequest, retarget

    tmp = tmp_path_factory.mktemp("plot")
    with pytest.MonkeyPatch.context() as mp:  # module-scoped: the environment restored after the two runs
        mp.setenv("WBMP_COMPILE", "0")
        mp.setenv("WBMP_CACHE_DIR", str(tmp / "cache"))
        code = main(["retarget", str(DANCE), "--robot", "talos", *WINDOW, "--no-sim", "--json",
                     "--out", str(tmp / "m.npz"), "--plot", str(tmp / "plots") + "/"])
        result = retarget(RetargetRequest(clip=str(DANCE), robot="talos", start=0.0, end=0.6, simulate=False),
                          cache=True, cache_dir=tmp / "cache" / "motions")
    return code, tmp, result


def test_the_plot_is_a_png_of_plausible_size(run, capsys):
    code, tmp, _ = run
    assert code == 0
    png = tmp / "plots" / "18_15_dance_keypoints.png"
    raw = png.read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n" and raw[12:16] == b"IHDR"
    width, height = struct.unpack(">II", raw[16:24])
    assert 800 <= width <= 3000 and 1000 <= height <= 3000  # 8 rows of 4 panels
    assert 40_000 < len(raw) < 3_000_000
    assert sorted(p.name for p in (tmp / "plots").iterdir()) == ["18_15_dance_keypoints.png"]  # no temporary left


def test_the_plotted_data_are_the_reported_figures(run):
    from wbmp.retarget import keypoint_plot

    _, tmp, result = run
    assert result.cached is not None  # the CLI run's plan, read back
    data = keypoint_plot(result)
    report = json.loads(json.dumps(result.report()["retarget"]["plan"]))
    role, time, worst = data.worst()
    assert worst == pytest.approx(report["tracking_max_m"], abs=1e-12)
    assert f"max {report['tracking_max_m']:.3f} m" in data.annotation()
    assert f"mean {report['tracking_mean_m']:.3f} m" in data.annotation()
    assert role.replace("_", " ") in report["worst"] and f"at {time:.2f} s" in report["worst"]
    # the robot's keypoints are the planned configurations' forward kinematics (Pinocchio, here)
    robot, plan, ref = result.model(), result.plan, result.reference
    d = robot.model.createData()
    inside = (plan.t >= ref.t[0] - 1e-9) & (plan.t <= ref.t[-1] + 1e-9)
    np.testing.assert_allclose(data.t, plan.t[inside])
    for k, qk in enumerate(plan.q[inside]):
        pin.framesForwardKinematics(robot.model, d, qk)
        for r in ("base", "head", "left_hand", "right_foot"):
            np.testing.assert_allclose(data.robot[r][k], d.oMf[robot.model.getFrameId(robot.frame(r))].translation,
                                       atol=1e-9)
        # the source is the scaled reference at the nearest clip frame
        i = int(np.argmin(np.abs(ref.t - data.t[k])))
        np.testing.assert_allclose(data.source["left_hand"][k], ref.points["left_hand"][i], atol=1e-12)
    # the dance keeps both feet down: shaded throughout, the soles within the float figure of the floor
    for side in ("left", "right"):
        assert data.contact[side].all()
        assert np.abs(data.foot_height[side]).max() <= 1e-3 * max(report["float_mm"], report["penetration_mm"]) + 1e-6


@pytest.mark.parametrize("plot", ["keypoints.txt", "same"])
def test_a_bad_plot_path_exits_2_before_any_work(plot, tmp_path, capsys):
    out = tmp_path / "m.npz"
    target = str(out) if plot == "same" else str(tmp_path / plot)
    code = main(["retarget", str(DANCE), *WINDOW, "--no-sim", "--quiet", "--out", str(out), "--plot", target])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--plot" in err and len(err.splitlines()) == 1
    assert not any(tmp_path.iterdir())
