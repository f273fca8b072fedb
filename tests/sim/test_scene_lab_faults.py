"""Faults of a scene's virtual lab (sim/scene_lab.py), each test with a lab of its own: an arm
whose sleeve is out of the endoscope's view is held and disabled alone while the other walks; an
emergency stop on one box stops every arm safely.

Apart from tests/sim/test_scene_lab.py because that module's lab (a module-scoped fixture) renders
two arms at 16.67 fps until the module ends, ~1.5 of this machine's 2 cores: a wall-clock test
that started its own lab beside it saw its loop starved (a walked 65 cycles of 83 in 5 s)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.sim.test_scene_lab import FPS, ONE_ARM_VIEW_SCALE, ROOT, SCALE, SCENE
from tests.sim.test_virtual_lab import NO_SIM, RT_HOST, RT_LAB, hardware_servo
from wristmark.rig.loop.scene_file import Scene
from wristmark.sim.scene_lab import read_scene_truth_csv, scene_true_tip_errors
from wristmark_testing.lab_process import read_lines, scene_lab_command, stop


@pytest.mark.slow
@pytest.mark.network
@pytest.mark.wallclock
def test_an_arm_whose_sleeve_is_out_of_view_is_held_and_disabled_alone(tmp_path: Path) -> None:
    """b stands 600 mm away, outside the endoscope's view (the one-arm bench's camera): its loop
    holds it, then its box alone is held and disabled; a walks its cube to the end."""
    scenes = ROOT / "configs" / "scenes"
    scene_file = tmp_path / "b_out_of_view.yaml"
    scene_file.write_text(
        f"camera: {ROOT / 'configs' / 'camera.yaml'}\narms:\n"
        f"  - marker: {scenes / 'two_arms' / 'a.yaml'}\n"
        f"  - marker: {scenes / 'two_arms' / 'b.yaml'}\n"
        "    base: {xyz: [0.6, 0.0, 0.0], rpy: [0.0, 0.0, 3.141592653589793]}\n")
    truth, calib, out = tmp_path / "truth.csv", tmp_path / "calib.yaml", tmp_path / "run"
    lab = subprocess.Popen(scene_lab_command(str(scene_file), ONE_ARM_VIEW_SCALE, FPS, str(truth), str(calib), *RT_LAB),
                           cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        lines = read_lines(lab, 3, timeout=90)
        ptys = dict(line.split(" ", 1) for line in lines[:2])
        r = hardware_servo("--scene", str(scene_file), "--serial", f"a={ptys['a']}", "--serial", f"b={ptys['b']}",
                           "--camera", lines[2], "--calib", str(calib), "--image-scale", str(ONE_ARM_VIEW_SCALE),
                           "--duration", "5", "--out", str(out), "--no-progress", *RT_HOST)
    finally:
        rc, err = stop(lab)
        assert rc == 0, err
    assert r.returncode == 3, r.stdout + r.stderr
    stderr = r.stderr.strip()
    assert "\n" not in stderr and "arm b" in stderr and "marker lost" in stderr and "arm a" not in stderr
    res = json.loads((out / "result.json").read_text())
    a, b = res["arms"]["a"], res["arms"]["b"]
    assert not a["stopped"] and b["cause"] == "marker-lost" and b["safe_stop"]["held_and_disabled"]
    # b stopped max_lost_cycles (1.5 s) after its first cycle, in the settle or just after it
    assert a["closed_loop"]["cycles"] > 70 and b["closed_loop"]["cycles"] < 0.25 * a["closed_loop"]["cycles"]
    scene = Scene.load(scene_file)
    err = scene_true_tip_errors(out / "log_a.csv", truth, "a", scene.arms[0].base)
    err = err[np.isfinite(err)]
    cl = a["closed_loop"]
    probe = cl["play_probe"]
    plays = [round(1e6 * f["play"]) for f in probe] if isinstance(probe, list) else probe
    assert err.size > 70 and 1000 * np.median(err) < 0.5, (  # what a buzz or a slow host would show
        f"a's true tip {1000 * np.median(err):.3f} mm median; probed plays {plays} um/urad, "
        f"{cl['play_shrinks']} shrunk; lost {cl['lost']}, no frame {cl['no_frame']}, skipped {cl['skipped']}")
    t, tips = read_scene_truth_csv(truth)
    late = t > t[-1] - 2.0  # while a still walked, b stood still: held, then disabled
    assert np.ptp(tips["b"][late], axis=0).max() < 1e-6 and np.ptp(tips["a"][late], axis=0).max() > 1e-3


@pytest.mark.slow
@pytest.mark.network
@pytest.mark.wallclock
def test_an_emergency_stop_on_one_box_stops_every_arm_safely(tmp_path: Path) -> None:
    """The scene's lab in this process; mid-run b's box is emergency-stopped: the host holds and
    disables a's box too (not its watchdog) and says so in one line, exit 3."""
    from wristmark.cvs.calibration.load import save_calibration
    from wristmark.rig.link import protocol as P
    from wristmark.sim.scene_lab import SceneLab
    from wristmark.sim.scene_setup import load_scene_setup
    from wristmark.sim.virtual_lab import LabCamera

    setup = load_scene_setup(SCENE)
    calib = tmp_path / "calib.yaml"
    save_calibration(calib, setup.camera)
    with SceneLab(setup, LabCamera(fps=FPS, image_scale=SCALE)) as lab:
        ptys, url = lab.start()
        host = subprocess.Popen(
            [sys.executable, "-c", NO_SIM, "servo", "--scene", SCENE, "--serial", f"a={ptys['a']}", "--serial",
             f"b={ptys['b']}", "--camera", url, "--calib", str(calib), "--image-scale", str(SCALE), "--duration", "20",
             "--no-progress", *RT_HOST], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        a, b = lab.emulators["a"], lab.emulators["b"]
        deadline = time.monotonic() + 60
        while not (a.enabled and b.enabled) and time.monotonic() < deadline and host.poll() is None:
            time.sleep(0.05)
        assert a.enabled and b.enabled, host.communicate(timeout=20)[1]
        time.sleep(3.0)  # the arms ramp to their starts and rest there
        b.receive(P.encode(P.EStop(seq=0)))  # the operator's button on b's box
        _, err = host.communicate(timeout=30)
    assert host.returncode == 3, err
    line = err.strip()
    assert "\n" not in line and "emergency stop: arm 'b'" in line and "arm a at" in line and "arm b at" in line
    assert b.estopped and not b.enabled
    assert not a.enabled and not a.watchdog_tripped and not a.estopped  # a held and disabled by the host
