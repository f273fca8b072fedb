"""controller.yaml grouped by concern (paper, qp, backlash, probe): every key in one section,
the flat layout (every key under controller:) still meaning the same, and a sweep's dotted keys
with or without the section."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.config_io import load_yaml, to_mapping
from wristmark.models.errors import ConfigError
from wristmark.solvers.controller import CONTROLLER_LAYOUT, CONTROLLER_SECTIONS, ControllerConfig


def test_every_key_but_kind_and_dt_is_in_one_section() -> None:
    keys = [k for _, ks in CONTROLLER_SECTIONS.values() for k in ks]
    assert len(keys) == len(set(keys))
    assert set(keys) == {f.name for f in dataclasses.fields(ControllerConfig)} - {"kind", "dt"}


def test_the_shipped_file_is_grouped_and_states_every_key_but_dt() -> None:
    raw = load_yaml(CONFIG_DIR / "controller.yaml")["controller"]
    assert set(raw) == {"kind", *CONTROLLER_SECTIONS}
    for name, (_, keys) in CONTROLLER_SECTIONS.items():
        assert set(raw[name]) == set(keys), name
    sections = ControllerConfig().sections()
    sections.pop("dt")  # the loop's (rig.yaml control_dt)
    assert sections == raw


def test_a_flat_file_means_the_same_as_the_grouped_one(tmp_path: Path) -> None:
    flat = tmp_path / "flat.yaml"
    flat.write_text(yaml.safe_dump({"controller": to_mapping(ControllerConfig())}))
    assert ControllerConfig.load(flat) == ControllerConfig.load(CONFIG_DIR / "controller.yaml")


@pytest.mark.parametrize("text", [
    "extends: controller.yaml\ncontroller:\n  ki: 1.0\n  backlash_lead: 0.0\n",
    "extends: controller.yaml\ncontroller:\n  qp:\n    ki: 1.0\n  backlash:\n    backlash_lead: 0.0\n",
    "extends: controller_plain.yaml\ncontroller:\n  qp: {ki: 1.0, lever: 0.2, integral_mode: path}\n"
    "  backlash: {backlash_lead: 0.0, backlash_compensation: true, backlash_start: 0.15, backlash_fraction: 0.75,\n"
    "    backlash_method: encoders, backlash_margin: 0.01, backlash_freeze: 0.5, backlash_motor_burst: true,\n"
    "    backlash_kinds: [qp]}\n  probe: {play_probe: true, play_probe_learning: false}\n",
])
def test_an_overlay_may_be_flat_or_grouped(tmp_path: Path, text: str) -> None:
    f = tmp_path / "c.yaml"
    f.write_text(text)
    assert ControllerConfig.load(f) == dataclasses.replace(ControllerConfig(), ki=1.0, backlash_lead=0.0)


@pytest.mark.parametrize("text, words", [
    ("controller:\n  qp:\n    backlash_start: 0.2\n", ["'backlash_start' belongs under 'backlash:'", "not 'qp:'"]),
    ("controller:\n  kind: qp\n  qp: {kp: 8.0}\n  ki: 1.0\n", ["'ki' is outside the sections", "put it under 'qp:'"]),
    ("controller:\n  probe:\n    amplitude: 2.0\n", ["unknown key 'probe.amplitude'", "play_probe_amplitude"]),
    ("controller:\n  paper: 1\n", ["'paper' must be a mapping"]),
    ("controller:\n  qp:\n    ki: -1.0\n", ["'ki' must be >= 0"]),
])
def test_a_key_in_the_wrong_section_is_one_line(tmp_path: Path, text: str, words: list[str]) -> None:
    f = tmp_path / "c.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        ControllerConfig.load(f)
    msg = str(e.value)
    assert msg.startswith(str(f)) and "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_a_sweeps_controller_key_with_or_without_its_section(tmp_path: Path) -> None:
    from wristmark.sweep.spec import SpecError, load_spec

    spec = tmp_path / "s.yaml"
    spec.write_text(yaml.safe_dump({"experiment": "cube", "set": {"controller.qp.kp": 6.0, "controller.ki": 2.0},
                                    "grid": {"controller.backlash.backlash_play_max.0": [0.01, 0.02]}}))
    s = load_spec(spec)
    for t, play in zip(s.trials, (0.01, 0.02)):
        c = t.configs["controller"]
        assert c["kp"] == 6.0 and c["ki"] == 2.0 and c["backlash_play_max"][0] == play
    spec.write_text(yaml.safe_dump({"experiment": "cube", "grid": {"controller.probe.ki": [1.0]}}))
    with pytest.raises(SpecError, match="'ki' is in controller.yaml's 'qp:' section"):
        load_spec(spec)


def test_the_layout_names_each_key_once() -> None:
    assert CONTROLLER_LAYOUT["ki"] == "qp" and CONTROLLER_LAYOUT["play_probe"] == "probe"
    assert "kind" not in CONTROLLER_LAYOUT and "dt" not in CONTROLLER_LAYOUT
