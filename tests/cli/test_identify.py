"""`wristmark identify` as a user runs it (subprocess): a short excitation on the simulated bench
with the vision in the loop writes a model file, offline from its record gives the same fit, the
same over the virtual lab's pty and MJPEG stream (`wristmark emulator --pty --camera-port 0`, its
own process), and bad input is one line with exit 2."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from tests.sim.test_virtual_lab import RT_HOST, RT_LAB
from wristmark_testing.lab_process import read_lines, stop

ROOT = Path(__file__).resolve().parents[2]
UNSEEN = "wristmark/configs/plant_unseen.yaml"


def wristmark(*args: str, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "wristmark", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def identify_on_the_bench_and_offline(tmp_path: Path, *options: str) -> tuple[dict, dict]:
    """(the model identify writes on the bench with ``options`` and --log, the one refitted
    offline from that record). Half-size frames: a quarter of the rendering and tracking; the
    fits agree with full size's within the tolerances below (2026-12-04: gains 1.059 / 0.881,
    rms 0.149 mm with 12 poses; stiffness 0.350 / 0.122, load 0.029 / 0.048 / -0.081 N)."""
    r = wristmark("identify", "--plant", UNSEEN, *options, "--image-scale", "0.5", "--out", str(tmp_path / "m.yaml"),
                  "--log", str(tmp_path / "log"), "--no-progress")
    assert r.returncode == 0, r.stderr
    off = wristmark("identify", "--from-log", str(tmp_path / "log"), "--out", str(tmp_path / "m2.yaml"))
    assert off.returncode == 0, off.stderr
    return yaml.safe_load((tmp_path / "m.yaml").read_text()), yaml.safe_load((tmp_path / "m2.yaml").read_text())


@pytest.mark.slow
def test_identify_on_the_bench_then_offline_from_its_record(tmp_path: Path) -> None:
    model, again = identify_on_the_bench_and_offline(tmp_path, "--poses", "12")
    assert model["poses"] >= 12 and model["rms_m"] < 3e-4
    assert model["bend_gain"] == pytest.approx([1.06, 0.88], abs=0.02)  # the unseen plant's truth
    assert any("stem-rotation" in note for note in model["not_separable"])
    assert again["bend_gain"] == pytest.approx(model["bend_gain"], abs=1e-9)


@pytest.mark.parametrize("args, cause", [
    (("--serial", "/dev/null", "--camera", "0"), "--serial/--camera"),
    (("--from-log", "nowhere"), "--from-log: neither excitation.npz"),
    (("--from-log", "nowhere", "--load", "0.1"), "--load are for the simulated bench"),
    (("--plant", "missing.yaml"), "missing.yaml"),
    (("--load", "0.1", "--load-direction", "0", "0", "0"), "direction must be 3 finite numbers"),
    (("--serial", "/dev/null", "--camera", "0", "--calib", "wristmark/configs/camera.yaml", "--load", "0.1",
      "--load-direction", "nan", "0", "1"), "--load-direction: 'nan' is not a finite number"),
    (("--serial", "/dev/null"), "needs both --serial PORT and --camera SPEC"),
    (("--serial", "/dev/null", "--camera", "0"), "need --calib CALIB"),
    (("--serial", "/dev/no-such-port", "--camera", "0", "--calib", "wristmark/configs/camera.yaml"),
     "/dev/no-such-port"),
    (("--rt-priority", "20"), "--rt-priority is for the hardware path"),
    (("--serial", "/dev/null", "--camera", "0", "--calib", "wristmark/configs/camera.yaml", "--rt-priority", "0"),
     "--rt-priority"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, args: tuple[str, ...], cause: str) -> None:
    r = wristmark("identify", *args, "--out", str(tmp_path / "m.yaml"), timeout=60)
    assert r.returncode == 2
    assert cause in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "m.yaml").exists()


def test_the_hardware_path_never_imports_the_simulated_bench(tmp_path: Path) -> None:
    code = ("import sys\nfrom wristmark.cli.main import main\nsys.argv = ['wristmark', 'identify', '--serial', "
            "'/dev/no-such-port', '--camera', '0', '--calib', 'wristmark/configs/camera.yaml', '--out', "
            f"{str(tmp_path / 'm.yaml')!r}]\nrc = main()\n"
            "print(rc, sorted(m for m in sys.modules if m.startswith('wristmark.sim')))")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert r.stdout.strip() == "2 []", r.stdout + r.stderr  # refused at the port, bench never loaded


@pytest.mark.slow
def test_identify_offline_from_a_servo_run_of_the_unseen_arm(tmp_path: Path) -> None:
    # a closed-loop cube on the unseen plant (no excitation of its own): its log.csv keeps the box's
    # targets and encoders every cycle, and the tracked tips at their capture
    # (half-size frames: a quarter of the rendering and tracking, the same fit)
    run = wristmark("experiment", "cube", "--plant", UNSEEN, "--duration", "16", "--image-scale", "0.5", "--out",
                    str(tmp_path / "run"), "--no-progress")
    assert run.returncode == 0, run.stderr
    r = wristmark("identify", "--from-log", str(tmp_path / "run"), "--out", str(tmp_path / "m.yaml"))
    assert r.returncode == 0, r.stderr
    assert "servo run" in r.stderr
    model = yaml.safe_load((tmp_path / "m.yaml").read_text())
    # measured at half size (2026-12-04): 301 tips, rms 0.101 mm, gains 1.067 / 0.885, offsets -0.064 / 0.065 rad,
    # lag 0.071 s (full size: rms 0.046 mm, the rest the same to 0.002)
    assert model["poses"] >= 200 and model["rms_m"] < 1.5e-4
    assert model["bend_gain"] == pytest.approx([1.06, 0.88], abs=0.02)  # the unseen plant's truth
    assert model["plane_offset"] == pytest.approx([-0.06, 0.08], abs=0.03)
    assert model["actuator_tau"] == pytest.approx(0.07, abs=0.01)


@pytest.mark.slow
def test_a_known_load_on_the_bench_gives_the_stiffness_and_the_arms_own_load(tmp_path: Path) -> None:
    model, again = identify_on_the_bench_and_offline(tmp_path, "--load", "0.15")
    # the unseen plant's truth: stiffness [0.35, 0.12] N m/rad, its own load [0.03, 0.05, -0.08] N;
    # measured: 0.349 / 0.123 and 0.030 / 0.049 / -0.079
    assert model["segment_stiffness"] == pytest.approx([0.35, 0.12], rel=0.1)
    assert model["tip_force"] == pytest.approx([0.03, 0.05, -0.08], abs=0.01)
    assert not any(note.startswith("tip_force ~ segment_stiffness") for note in model["not_separable"])
    assert again["segment_stiffness"] == pytest.approx(model["segment_stiffness"], abs=1e-9)


@pytest.mark.slow
def test_identify_also_registers_the_camera_from_the_same_excitation(tmp_path: Path) -> None:
    import numpy as np
    from scipy.spatial.transform import Rotation

    from wristmark.cvs.calibration.registration_file import load_registration
    from wristmark.sim.setup import load_setup

    plant = "wristmark/configs/plant_misplaced_camera.yaml"  # the camera 5.8 mm and 3.2 deg from the calibration's
    r = wristmark("identify", "--plant", plant, "--out", str(tmp_path / "m.yaml"), "--register-out",
                  str(tmp_path / "reg.yaml"), "--no-progress")
    assert r.returncode == 0, r.stderr
    truth = load_setup(plant=plant).true_camera.T_world_left
    error = np.linalg.inv(truth) @ load_registration(tmp_path / "reg.yaml").world_T_left
    turn = np.degrees(np.linalg.norm(Rotation.from_matrix(error[:3, :3]).as_rotvec()))
    # measured: 1.10 mm, 0.554 deg; `wristmark register` on the same plant: 0.92 mm, 0.560 deg. Left
    # in both: the plant's segment-1 plane offset (0.01 rad = 0.57 deg), a turn about z_w no
    # camera registration can tell from the camera's
    assert np.linalg.norm(error[:3, 3]) < 1.5e-3 and turn < 0.7
    model = yaml.safe_load((tmp_path / "m.yaml").read_text())
    assert model["registration"] == str(tmp_path / "reg.yaml")
    assert model["bend_gain"] == pytest.approx([0.98, 0.945], abs=0.01)  # configs/plant.yaml's truth
    assert "camera_rot[2]" in model["std_errors"]


def test_a_run_log_without_the_actuators_columns_is_refused(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "log.csv").write_text("t,phase,psi_cmd_0,psi_true_0,p_est_x\n0.0,servo,0.1,,0.05\n")
    r = wristmark("identify", "--from-log", str(run), "--out", str(tmp_path / "m.yaml"), timeout=60)
    assert r.returncode == 2
    assert "no column 't_act'" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "m.yaml").exists()


def test_experiment_refuses_a_plant_file_as_model() -> None:
    r = wristmark("experiment", "cube", "--model", UNSEEN, "--duration", "0.5", timeout=60)
    assert r.returncode == 2
    assert "not a model file" in r.stderr and len(r.stderr.strip().splitlines()) == 1


# -- the virtual lab ----------------------------------------------------------------------------
LAB_SCALE = 0.35  # the lab's endoscope at 0.35 x the calibration (as tests/sim/test_virtual_lab.py)
GAIN_TOL, OFFSET_TOL = 0.03, 0.04  # [-], [rad]: see the test on the virtual lab below


@dataclass
class Lab:
    """The virtual lab's process, its actuator box's pty and its camera's URL."""

    proc: subprocess.Popen[bytes]
    pty: str
    url: str

    def hang(self, force: str) -> None:
        """Hang the tip force 'FX FY FZ' [N] in {w} on the lab's arm (its --loads-from-stdin)."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"load {force}\n".encode())
        self.proc.stdin.flush()


@pytest.fixture(scope="module")
def lab() -> Iterator[Lab]:
    """The virtual lab with the unseen plant as its true arm, its own process."""
    proc = subprocess.Popen([sys.executable, "-m", "wristmark", "emulator", "--pty", "--camera-port", "0",
                             "--fps", "30", "--image-scale", str(LAB_SCALE), "--jpeg-quality", "95",
                             "--plant", UNSEEN, "--loads-from-stdin", *RT_LAB], cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        pty, url = read_lines(proc, 2, timeout=60)
        assert pty.startswith("/dev/") and url.startswith("http://127.0.0.1:")
        yield Lab(proc, pty, url)
    finally:
        rc, err = stop(proc)
        assert rc == 0, err


@pytest.mark.slow
@pytest.mark.network
@pytest.mark.wallclock
def test_a_camera_without_frames_is_one_line_and_leaves_the_box_disabled(lab: Lab, tmp_path: Path) -> None:
    from wristmark.rig.link.actuator_driver import ActuatorDriver

    pty = lab.pty
    out = tmp_path / "m.yaml"
    r = wristmark("identify", "--serial", pty, "--camera", "http://127.0.0.1:9/stream.mjpg", "--calib",
                  "wristmark/configs/camera.yaml", "--poses", "8", "--out", str(out), "--no-progress", timeout=90)
    assert r.returncode == 2, r.stderr
    assert "127.0.0.1:9" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()
    with ActuatorDriver(pty, timeout=0.2, retries=3) as box:
        assert not box.get_state().enabled  # never enabled: the arm holds where it was


@pytest.mark.slow
@pytest.mark.network
@pytest.mark.wallclock
def test_identify_on_the_virtual_lab_finds_the_lab_arm_and_a_known_loads_stiffness(lab: Lab, tmp_path: Path) -> None:
    """identify on the hardware path (the lab's pty and MJPEG stream, the wall clock) finds the
    lab's arm; with --load it asks for the weight once, halfway, and waits for Enter with the box
    fed: here the 'person' hangs it on the lab's arm (its stdin) and presses Enter."""
    out = tmp_path / "m.yaml"
    proc = subprocess.Popen([sys.executable, "-m", "wristmark", "identify", "--serial", lab.pty, "--camera", lab.url,
                             "--calib", "wristmark/configs/camera.yaml", "--image-scale", str(LAB_SCALE), "--poses",
                             "16", "--load", "0.3", "--out", str(out), "--no-progress", *RT_HOST],
                            cwd=ROOT, stdin=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdin is not None and proc.stderr is not None
    asked = []
    try:
        for line in proc.stderr:
            asked.append(line)
            if "press Enter" in line:
                lab.hang("0 0 -0.3")
                time.sleep(0.3)
                proc.stdin.write("\n")
                proc.stdin.flush()
        assert proc.wait(timeout=240) == 0, "".join(asked)
    finally:
        lab.hang("0 0 0")
        if proc.poll() is None:
            proc.kill()
    assert sum("press Enter" in line for line in asked) == 1  # one weight, hung once
    assert any("take the weight off" in line for line in asked)
    model = yaml.safe_load(out.read_text())
    # At 0.35 scale the marker is not found at some of the poses (turned away); the fit needs 8.
    # 2026-12-04, load ~11: 22 and 21 tips, rms 0.26 / 0.25 mm.
    assert model["poses"] >= 8 and model["rms_m"] < 5e-4
    # The lab's plant (configs/plant_unseen.yaml): gains [1.06, 0.88], offsets [-0.06, 0.08] rad,
    # lag 0.07 s. Without a load, 12 poses, on the loaded machine (two runs): gains within 0.004
    # and 0.013, offsets within 0.005 and 0.008 rad; 8 poses up to 0.053 / 0.047 (gains and offsets
    # then correlate above 0.99). With a 0.3 N load, 16 poses (2026-12-04, two runs, idle machine):
    # gains within 0.004, offsets within 0.015 rad, lag 0.0705 / 0.0704 s.
    assert model["bend_gain"] == pytest.approx([1.06, 0.88], abs=GAIN_TOL)
    assert model["plane_offset"] == pytest.approx([-0.06, 0.08], abs=OFFSET_TOL)
    assert model["actuator_tau"] == pytest.approx(0.07, abs=0.01)
    # the unseen plant's truth: stiffness [0.35, 0.12] N m/rad, its own load [0.03, 0.05, -0.08] N.
    # The weight is 0.3 N: with 0.15 N the fit's own standard error of the second stiffness was
    # 0.017 N m/rad, as large as this bound (0.134 / 0.135 in two runs, 0.139 in a CI run); with
    # 0.3 N it is 0.0076 (2026-12-04, idle machine, two runs: 0.347 / 0.127 and 0.343 / 0.129,
    # own load 0.026 / 0.045 / -0.089 and 0.030 / 0.048 / -0.073 N, its standard error 0.023 N in z)
    assert model["segment_stiffness"] == pytest.approx([0.35, 0.12], rel=0.15)
    assert model["tip_force"] == pytest.approx([0.03, 0.05, -0.08], abs=0.02)
