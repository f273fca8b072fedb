"""Files that would eat the machine are refused before they are parsed (issue 17, item 4).

A 1 KB YAML file of nested aliases (the "billion laughs") and files over the 1 MB limit
(configuration, calibration YAML, OpenCV FileStorage) end in one ConfigError in under a second
and under 100 MB of memory, measured in a fresh process (peak RSS growth, resource.getrusage).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from wristmark.models.config_io import MAX_CONFIG_BYTES, load_yaml
from wristmark.models.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ("models", "cvs", "solvers", "rig", "sim", "viz")

LEVELS = ["a", "b", "c", "d", "e", "f", "g", "h", "i"]
# 9 levels of 9 aliases: 9^9 (387 million) strings once expanded, e.g. by the repr in an error message
BOMB = "stem_coupling: [\n  &a [lol, lol, lol, lol, lol, lol, lol, lol, lol],\n" + "".join(
    f"  &{x} [{', '.join(['*' + prev] * 9)}],\n" for prev, x in zip(LEVELS, LEVELS[1:])) + "]\n"

MEASURE = """
import json, resource, sys, time
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))  # the test must not take the machine down
from wristmark.models.errors import ConfigError
import {module}
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
try:
    {call}
    error = None
except ConfigError as e:
    error = str(e)
except MemoryError:
    error = "MemoryError"
seconds = time.perf_counter() - t0
grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
print(json.dumps({{"error": error, "seconds": seconds, "grown_mb": grown_mb}}))
"""


def measure(module: str, call: str) -> dict:
    code = MEASURE.format(module=module, call=call)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout.strip().splitlines()[-1])


def assert_refused_cheaply(res: dict, *words: str) -> None:
    assert res["error"] is not None and res["error"] != "MemoryError", res
    assert "\n" not in res["error"]
    for w in words:
        assert w in res["error"], res["error"]
    assert res["seconds"] < 1.0, res
    assert res["grown_mb"] < 100, res


def test_alias_bomb_is_refused_at_once(tmp_path: Path) -> None:
    f = tmp_path / "plant.yaml"
    f.write_text(BOMB)
    assert f.stat().st_size < 1100
    res = measure("wristmark.sim.plant_params", f"wristmark.sim.plant_params.PlantParams.load({str(f)!r})")
    assert_refused_cheaply(res, "plant.yaml:2:", "anchors and aliases are not allowed", "&a")


def test_oversized_config_is_refused_before_reading(tmp_path: Path) -> None:
    f = tmp_path / "rig.yaml"
    with open(f, "wb") as fh:  # a sparse 200 MB file: "control_dt: 0.06" then zeros
        fh.write(b"control_dt: 0.06\n")
        fh.truncate(200 * 10**6)
    res = measure("wristmark.models.config_io", f"wristmark.models.config_io.load_yaml({str(f)!r})")
    assert_refused_cheaply(res, "rig.yaml", "200.0 MB", "1.0 MB limit")


@pytest.mark.parametrize("head", [b"image_size: [1920, 1080]\n", b"%YAML:1.0\n---\nM1: !!opencv-matrix\n"])
def test_oversized_calibration_is_refused_before_reading(tmp_path: Path, head: bytes) -> None:
    """Both the YAML and the OpenCV FileStorage paths of cvs.calibration.load."""
    f = tmp_path / "calib.yml"
    with open(f, "wb") as fh:
        fh.write(head)
        fh.truncate(200 * 10**6)
    res = measure("wristmark.cvs.calibration.load", f"wristmark.cvs.calibration.load.load_calibration({str(f)!r})")
    assert_refused_cheaply(res, "calib.yml", "calibration file", "limit")


def test_a_file_at_the_limit_still_loads(tmp_path: Path) -> None:
    f = tmp_path / "c.yaml"
    body = "control_dt: 0.06\n"
    f.write_text(body + "#" * (MAX_CONFIG_BYTES - len(body) - 1) + "\n")
    assert f.stat().st_size == MAX_CONFIG_BYTES
    assert load_yaml(f) == {"control_dt": 0.06}


@pytest.mark.parametrize(("text", "needle"), [
    ("a: &x 1\nb: 2\n", "'&x'"),
    ("a: 1\nb: *x\n", "'*x'"),
    ("base: &b {k: 1}\nother:\n  <<: *b\n", "'&b'"),
])
def test_anchors_and_aliases_are_refused(tmp_path: Path, text: str, needle: str) -> None:
    f = tmp_path / "m.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(needle)):
        load_yaml(f)


@pytest.mark.parametrize(("text", "line"), [
    ("control_dt: 0.06\ngate: 0.004\ncontrol_dt: 0.11\n", 3),  # YAML alone would keep the last
    ("controller:\n  kp: 8.0\n  ki: 4.0\n  kp: 5.0\n", 4),
])
def test_a_key_given_twice_is_refused_with_its_line(tmp_path: Path, text: str, line: int) -> None:
    f = tmp_path / "rig.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(f"rig.yaml:{line}: key '") + ".*' is given twice"):
        load_yaml(f)
    f.write_text("a:\n  k: 1\nb:\n  k: 2\n")  # the same key in two mappings is fine
    assert load_yaml(f) == {"a": {"k": 1}, "b": {"k": 2}}


def test_deep_nesting_is_one_error(tmp_path: Path) -> None:
    f = tmp_path / "deep.yaml"
    f.write_text("a: " + "[" * 100_000 + "\n")
    with pytest.raises(ConfigError, match="deep.yaml"):
        load_yaml(f)


def test_the_command_line_reports_it_in_one_line(tmp_path: Path) -> None:
    f = tmp_path / "plant.yaml"
    f.write_text(BOMB)
    p = subprocess.run([sys.executable, "-m", "wristmark", "experiment", "cube", "--plant", str(f)], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert len(p.stderr.strip().splitlines()) == 1 and "aliases are not allowed" in p.stderr


def test_every_yaml_read_goes_through_load_yaml() -> None:
    """Product code parses YAML only in models/config_io.py (the loader without aliases)."""
    pattern = re.compile(r"yaml\.(safe_load|load|full_load|unsafe_load|load_all|safe_load_all|compose|parse)\(")
    offenders = []
    for pkg in PRODUCT:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if path.relative_to(ROOT).as_posix() == "models/config_io.py":
                continue
            for n, line in enumerate(path.read_text().splitlines(), 1):
                if pattern.search(line):
                    offenders.append(f"{path.relative_to(ROOT)}:{n}")
    assert not offenders, "YAML read outside models.config_io.load_yaml: " + ", ".join(offenders)
