"""A wheel of wristmark installs and runs outside the checkout: the wheel is built from a copy
of the sources, installed (``--no-deps``) into a new virtual environment, and ``wristmark fk``
and a 2-second ``wristmark experiment cube`` run from a temporary folder.

Installing every dependency from PyPI into a fresh venv takes minutes, so the test venv sees the
project venv's packages through a ``.pth`` file in its own site-packages: that path comes after
the venv's own site-packages, so the wheel's wristmark is the one imported (checked:
``wristmark.__file__`` lies inside the test venv). The project venv's editable-install hook is
not carried over."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from wristmark.models.config_files import shipped_configs
from wristmark.models.kinematics import tip_position
from wristmark.models.robot_params import HOME_PSI, RobotParams

pytestmark = [pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PROJECT_SITE = Path(sysconfig.get_paths()["purelib"])


def run(cmd: list[str], cwd: Path, env: dict[str, str] | None = None, timeout: float = 300) -> str:
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)
    assert r.returncode == 0, f"{cmd}: {r.stderr[-3000:]}"
    return r.stdout


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A wheel built from a copy of the package sources (the checkout stays untouched)."""
    src = tmp_path_factory.mktemp("src")
    shutil.copytree(ROOT / "wristmark", src / "wristmark", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    out = tmp_path_factory.mktemp("wheels")
    # build isolation: the project venv's setuptools may lack bdist_wheel; pip's cache makes it quick
    run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "-q", "-w", str(out)], cwd=src)
    (whl,) = out.glob("wristmark-*.whl")
    return whl


@pytest.fixture(scope="module")
def venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A new venv with only the wheel installed, seeing the project venv's dependencies."""
    root = tmp_path_factory.mktemp("venv")
    run([sys.executable, "-m", "venv", "--without-pip", str(root)], cwd=root)
    py = root / "bin" / "python"
    run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--no-index", "-q", str(wheel)],
        cwd=root)
    site = Path(run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=root).strip())
    # the dependencies' path, then the other .pth hooks of the project venv (pinocchio's cmeel), not the editable one
    hooks = [p.read_text() for p in sorted(PROJECT_SITE.glob("*.pth")) if not p.name.startswith("__editable__")]
    (site / "zz_wristmark_test_deps.pth").write_text("\n".join([str(PROJECT_SITE), *hooks]) + "\n")
    return root


def env_for(tmp_path: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")
    return env


def test_wheel_holds_the_package_and_its_configs(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "wristmark/__init__.py" in names and "wristmark/_lazy.py" in names
    assert "wristmark/cli/main.py" in names and "wristmark/sim/experiments.py" in names
    assert "wristmark/py.typed" in names
    configs = {f"wristmark/configs/{c}" for c in shipped_configs()}
    assert {"wristmark/configs/robot.yaml", "wristmark/configs/camera.yaml"} <= configs
    assert any(c.startswith("wristmark/configs/sweeps/") for c in configs)
    assert configs <= names, sorted(configs - names)
    assert not [n for n in names if n.startswith(("tests/", "bench/", "examples/"))]


def test_installed_wristmark_is_the_wheel(venv: Path, tmp_path: Path) -> None:
    out = run([str(venv / "bin" / "python"), "-c",
               "import wristmark, sys; print(wristmark.__file__); "
               "print(sys.modules[wristmark.MarkerTracker.__module__].__file__); "
               "print(wristmark.models.default_config('robot.yaml'))"],
              cwd=tmp_path, env=env_for(tmp_path))
    module_file, tracker_file, robot_yaml = out.splitlines()
    assert Path(module_file).resolve().is_relative_to(venv.resolve())
    assert Path(tracker_file).resolve().is_relative_to(venv.resolve())
    assert Path(robot_yaml).resolve().is_relative_to(venv.resolve()) and Path(robot_yaml).is_file()


def test_installed_fk(venv: Path, tmp_path: Path) -> None:
    out = run([str(venv / "bin" / "wristmark"), "fk", "--psi", *map(str, HOME_PSI), "--json"], cwd=tmp_path,
              env=env_for(tmp_path))
    res = json.loads(out)
    tip = res["tip"] if "tip" in res else res["tip_world"]
    expected = tip_position(RobotParams(), HOME_PSI)
    assert max(abs(a - b) for a, b in zip(tip, expected)) < 1e-12
    assert len(res["jacobian"]) == 6 and all(len(row) == 6 for row in res["jacobian"])


def test_installed_experiment_cube(venv: Path, tmp_path: Path) -> None:
    out = run([str(venv / "bin" / "wristmark"), "experiment", "cube", "--sensor", "truth-noise", "--duration", "2",
               "--json", "cube.json", "--no-progress"], cwd=tmp_path, env=env_for(tmp_path))
    assert "run folder: runs/cube-" in out
    res = json.loads((tmp_path / "cube.json").read_text())
    opened, closed = res["open_loop"], res["closed_loop"]
    assert opened["cycles"] >= 30 and closed["cycles"] >= 30  # 2 s at the 60 ms cycle
    assert closed["stopped"] == "" and closed["mean_mm"] < opened["mean_mm"]
    run_dirs = list((tmp_path / "runs").glob("cube-*"))
    assert len(run_dirs) == 1 and (run_dirs[0] / "result.json").is_file()
