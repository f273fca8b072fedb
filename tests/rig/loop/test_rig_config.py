"""RigConfig loading and validation."""

import dataclasses
from pathlib import Path

import pytest
import yaml

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.config_io import load_yaml, to_mapping
from wristmark.models.errors import ConfigError
from wristmark.rig.loop.rig_config import BENCH_KEYS, RigConfig

CONFIGS = CONFIG_DIR


def test_default_file_loads_and_matches_paper_cycle() -> None:
    cfg = RigConfig.load(CONFIGS / "rig.yaml")
    assert cfg.control_dt == pytest.approx(0.060)
    assert cfg.sensor == "vision"  # the real pipeline is the default


@pytest.mark.parametrize(
    "text, words",
    [
        ("control_dt: 0\n", ["control_dt", "> 0"]),
        ("control_dt: 0.03\nvision_latency: 0.05\n", ["vision_latency", "shorter"]),
        ("sensor: magic\n", ["sensor", "vision"]),
        ("render_noise: loud\n", ["render_noise"]),
        ("bogus: 1\n", ["unknown key 'bogus'"]),
        ("gate: [1, 2]\n", ["gate", "number"]),
        ("max_lost_cycles: 0\n", ["max_lost_cycles"]),
        ("frame_age: -0.01\n", ["frame_age", ">= 0"]),
        ("frame_age: 1.5\n", ["frame_age", "at most 1 s"]),
        ("frame_age: 0.1\nsensor: truth-noise\n", ["frame_age", "vision"]),
        ("delay_compensation_learn_window: -1\n", ["delay_compensation_learn_window", ">= 0"]),
        ("delay_compensation_learn_window: 1000\n", ["delay_compensation_learn_window", "at most 600 s"]),
        ("delay_compensation_learn_window: .nan\n", ["delay_compensation_learn_window", "finite"]),
        ("tracker_magnify: 0.5\n", ["tracker_magnify", "1..4"]),
        ("tracker_magnify: 9\n", ["tracker_magnify", "1..4"]),
    ],
)
def test_validation_errors_name_key_and_file(tmp_path: Path, text: str, words: list[str]) -> None:
    f = tmp_path / "rig.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        RigConfig.load(f)
    msg = str(e.value)
    assert str(f) in msg and "\n" not in msg
    for w in words:
        assert w in msg


def test_the_shipped_file_holds_every_key_in_its_section() -> None:
    """rig.yaml: the servo loop's keys under 'loop:', the simulated bench's under 'bench:', each once."""
    raw = load_yaml(CONFIGS / "rig.yaml")
    assert set(raw) == {"loop", "bench"}
    assert set(raw["bench"]) == set(BENCH_KEYS)
    assert set(raw["loop"]) == {f.name for f in dataclasses.fields(RigConfig)} - set(BENCH_KEYS)
    assert RigConfig.load(CONFIGS / "rig.yaml").sections() == raw


def test_a_flat_file_and_a_sectioned_one_mean_the_same(tmp_path: Path) -> None:
    shipped = RigConfig.load(CONFIGS / "rig.yaml")
    flat = tmp_path / "flat.yaml"
    flat.write_text(yaml.safe_dump(to_mapping(shipped)))
    assert RigConfig.load(flat) == shipped
    wrapped = tmp_path / "wrapped.yaml"
    wrapped.write_text(yaml.safe_dump({"rig": {"loop": {"control_dt": 0.05}, "bench": {"vision_latency": 0.03}}}))
    assert RigConfig.load(wrapped) == RigConfig.load(_write(tmp_path, "control_dt: 0.05\nvision_latency: 0.03\n"))


def test_an_overlay_may_be_flat_or_sectioned_over_a_sectioned_base(tmp_path: Path) -> None:
    expected = dataclasses.replace(RigConfig(), sensor="truth-noise", gate=0.005)
    for text in ("extends: rig.yaml\nsensor: truth-noise\ngate: 0.005\n",
                 "extends: rig.yaml\nbench:\n  sensor: truth-noise\nloop:\n  gate: 0.005\n"):
        assert RigConfig.load(_write(tmp_path, text)) == expected


@pytest.mark.parametrize("text, words", [
    ("loop:\n  sensor: vision\n", ["'sensor' belongs under 'bench:'", "not 'loop:'"]),
    ("bench:\n  control_dt: 0.06\n", ["'control_dt' belongs under 'loop:'"]),
    ("loop:\n  gate: 0.004\nsensor: vision\n", ["'sensor' is outside", "put it under 'bench:'"]),
    ("loop:\n  bogus: 1\n", ["unknown key 'loop.bogus'", "control_dt"]),
    ("bench: 3\n", ["'bench' must be a mapping"]),
])
def test_a_key_in_the_wrong_section_is_one_line(tmp_path: Path, text: str, words: list[str]) -> None:
    f = _write(tmp_path, text)
    with pytest.raises(ConfigError) as e:
        RigConfig.load(f)
    msg = str(e.value)
    assert msg.startswith(str(f)) and "\n" not in msg
    for w in words:
        assert w in msg, msg


def _write(folder: Path, text: str) -> Path:
    f = folder / "rig_x.yaml"
    f.write_text(text)
    return f


def test_a_sweeps_rig_key_may_name_its_section(tmp_path: Path) -> None:
    from wristmark.sweep.spec import SpecError, load_spec

    spec = _named(tmp_path / "s.yaml", yaml.safe_dump({
        "experiment": "cube", "set": {"rig.bench.sensor": "truth-noise", "rig.settle_time": 0.5},
        "grid": {"rig.loop.gate": [0.003, 0.005]}}))
    s = load_spec(spec)
    assert [t.configs["rig"]["gate"] for t in s.trials] == [0.003, 0.005]
    assert all(t.configs["rig"]["sensor"] == "truth-noise" and t.configs["rig"]["settle_time"] == 0.5
               for t in s.trials)
    bad = _named(tmp_path / "bad.yaml", yaml.safe_dump({"experiment": "cube", "grid": {"rig.loop.sensor": ["vision"]}}))
    with pytest.raises(SpecError, match="'sensor' is in rig.yaml's 'bench:' section"):
        load_spec(bad)


def _named(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_tracker_magnify_reaches_the_loops_tracker(tmp_path: Path) -> None:
    """rig loop ``tracker_magnify`` is the vision sensor's tracker's ``magnify`` (sim.setup)."""
    from wristmark.models.arm_spec import home_psi
    from wristmark.sim.setup import load_setup, make_measurement, make_plant

    f = tmp_path / "rig.yaml"
    f.write_text("loop:\n  tracker_magnify: 2\n")
    for rig, want in ((None, 1.0), (f, 2.0)):
        setup = load_setup(rig=rig)
        _, sensor = make_measurement(setup, make_plant(setup, home_psi(setup.params)), lambda: 0.0, 0)
        assert sensor.tracker.settings.magnify == want  # type: ignore[attr-defined]
