"""A sweep SPEC (docs/design.md "Sweeps"): parsed, validated and expanded into trials.

```yaml
experiment: cube                 # cube | point | accuracy | load
set: {sensor: truth-noise, duration: 10}             # fixed options of every trial
grid: {latency: [0.03, 0.045], plant.backlash.0: [0.0, 0.008]}   # cartesian product
random: {n: 4, seed: 0, ranges: {plant.bend_gain.0: [0.9, 1.1]}}  # seeded uniform samples
seeds: [0, 1]
```
Trials, in order: every grid point (the first key varying slowest) x every random sample x
every seed (fastest). Keys are ``wristmark experiment`` options or dotted configuration keys
(sweep.keys). Paths in file options are taken relative to the current folder, like every
wristmark option, and made absolute. Every trial is checked before any runs: its command line
by ``wristmark experiment``'s own parser, its configuration by loading it as the experiment
will (:func:`wristmark.cli.experiment.check_args`); the first bad one is a one-line SpecError.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cli.option_types import SEED_MAX
from wristmark.models.config_files import find_config
from wristmark.models.config_io import extends_chain, load_yaml
from wristmark.models.errors import ConfigError, WristmarkError
from wristmark.sweep.keys import (
    FILE_OPTIONS,
    NAMESPACES,
    ExperimentOptions,
    SpecError,
    check_value,
    format_value,
    set_dotted,
    split_dotted,
    write_configs,
)

TOP_KEYS = ("experiment", "set", "grid", "random", "seeds")
RANDOM_KEYS = ("n", "seed", "ranges")


@dataclass(frozen=True)
class Trial:
    """One seeded experiment run of a sweep.

    values: the swept keys as written in the SPEC -> this trial's value. args: its
    ``wristmark experiment`` option words (without seed, output and changed configuration files).
    configs: namespace -> complete mapping of each configuration file a dotted key changes.
    inputs: namespace -> SHA-256 of each other configuration file the experiment reads."""

    index: int
    seed: int
    values: dict[str, Any]
    args: tuple[str, ...]
    configs: dict[str, dict[str, Any]]
    inputs: dict[str, str]

    def argv(self, experiment: str, config_words: list[str]) -> list[str]:
        """``wristmark experiment`` words of this trial (output options not included)."""
        return ["experiment", experiment, *self.args, *config_words, "--seed", str(self.seed)]


@dataclass(frozen=True)
class SweepSpec:
    """A validated SPEC and its trials."""

    path: Path
    experiment: str
    fixed: dict[str, Any]
    grid: dict[str, list[Any]]
    random_n: int
    random_seed: int
    ranges: dict[str, tuple[float, float]]
    seeds: tuple[int, ...]
    trials: tuple[Trial, ...]

    @property
    def swept_keys(self) -> list[str]:
        """The keys that vary, as written: grid keys, then random keys."""
        return [*self.grid, *(self.ranges if self.random_n else {})]

    def fingerprint(self) -> str:
        """Hash of everything that decides the trials' results (SPEC and configuration contents)."""
        data = [self.experiment, [[t.index, t.seed, list(t.args), t.configs, t.inputs] for t in self.trials]]
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()

    def describe(self) -> dict[str, Any]:
        """The SPEC as plain data (sweep.json)."""
        return {"experiment": self.experiment, "set": self.fixed, "grid": self.grid,
                "random": {"n": self.random_n, "seed": self.random_seed,
                           "ranges": {k: list(v) for k, v in self.ranges.items()}},
                "seeds": list(self.seeds), "trials": len(self.trials)}


def load_spec(path: str | Path) -> SweepSpec:
    """Read, validate and expand a SPEC file; SpecError (one line) on anything wrong."""
    p = Path(path)
    try:
        data = load_yaml(p)
    except ConfigError as e:
        raise SpecError(f"sweep SPEC {e}") from None
    try:
        return _build(p, data)
    except ConfigError as e:
        raise SpecError(f"{p}: {e}") from None


def _mapping(data: Any, key: str) -> dict[str, Any]:
    if data is None:
        return {}
    if not isinstance(data, dict) or not all(isinstance(k, str) for k in data):
        raise SpecError(f"'{key}' must be a mapping of names to values, got {data!r}")
    return data


def _int(value: Any, key: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise SpecError(f"'{key}' must be an integer in [{lo}, {hi}], got {value!r}")
    return value


def _build(path: Path, data: Any) -> SweepSpec:
    if not isinstance(data, dict):
        raise SpecError(f"a SPEC is a mapping with keys {', '.join(TOP_KEYS)}")
    unknown = [k for k in data if k not in TOP_KEYS]
    if unknown:
        raise SpecError(f"unknown top-level key '{unknown[0]}' (valid: {', '.join(TOP_KEYS)})")
    options = ExperimentOptions()
    experiment = data.get("experiment")
    if not isinstance(experiment, str) or experiment not in options.experiments:
        raise SpecError(f"'experiment' must be one of {', '.join(options.experiments)}, got {experiment!r}")
    fixed = _mapping(data.get("set"), "set")
    grid = _mapping(data.get("grid"), "grid")
    if "grid" in data and not grid:
        raise SpecError("'grid' is empty: give at least one key with a list of values (or leave 'grid' out)")
    for k, values in grid.items():
        if not isinstance(values, list) or not values:
            raise SpecError(f"'grid.{k}' must be a non-empty list of values, got {values!r}")
    rnd = _mapping(data.get("random"), "random")
    bad = [k for k in rnd if k not in RANDOM_KEYS]
    if bad:
        raise SpecError(f"unknown key 'random.{bad[0]}' (valid: {', '.join(RANDOM_KEYS)})")
    n = _int(rnd.get("n", 0), "random.n", 0, 1_000_000)
    rseed = _int(rnd.get("seed", 0), "random.seed", 0, SEED_MAX)
    ranges = {k: _range(k, v) for k, v in _mapping(rnd.get("ranges"), "random.ranges").items()}
    if n and not ranges:
        raise SpecError("'random.n' > 0 needs 'random.ranges' (key: [low, high])")
    seeds_raw = data.get("seeds", [0])
    if not isinstance(seeds_raw, list) or not seeds_raw:
        raise SpecError(f"'seeds' must be a non-empty list of integers, got {seeds_raw!r}")
    seeds = tuple(_int(s, "seeds", 0, SEED_MAX) for s in seeds_raw)
    if len(set(seeds)) != len(seeds):
        raise SpecError(f"'seeds' lists a seed twice: {seeds_raw}")
    _check_distinct(options, [*fixed, *grid, *(ranges if n else {})])
    for k, v in fixed.items():
        check_value(f"set.{k}", v)
    for k, values in grid.items():
        check_value(f"grid.{k}", values)
    points = [dict(zip(grid, combo)) for combo in itertools.product(*grid.values())] if grid else [{}]
    trials = _expand(options, fixed, points, _samples(ranges, n, rseed), seeds)
    _validate(options, experiment, trials)
    return SweepSpec(path, experiment, fixed, grid, n, rseed, ranges, seeds, tuple(trials))


def _range(key: str, value: Any) -> tuple[float, float]:
    ok = (isinstance(value, list) and len(value) == 2
          and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value))
    if not ok:
        raise SpecError(f"'random.ranges.{key}' must be [low, high], two numbers, got {value!r}")
    check_value(f"random.ranges.{key}", value)
    lo, hi = float(value[0]), float(value[1])
    if lo > hi:
        raise SpecError(f"'random.ranges.{key}': low {lo} is above high {hi}")
    return lo, hi


def _check_distinct(options: ExperimentOptions, keys: list[str]) -> None:
    """Each key named once across set, grid and random (an option by either spelling)."""
    seen: dict[str, str] = {}
    for k in keys:
        canon = k if split_dotted(k) else options.action(k).dest
        if canon in seen:
            raise SpecError(f"'{k}' is given twice (also as '{seen[canon]}'): name each key in one place only")
        seen[canon] = k


def _samples(ranges: dict[str, tuple[float, float]], n: int, seed: int) -> list[dict[str, Any]]:
    """n seeded uniform samples of the ranges (one row per sample, keys in SPEC order)."""
    if not n:
        return [{}]
    lo = np.array([r[0] for r in ranges.values()])
    hi = np.array([r[1] for r in ranges.values()])
    draws = np.random.default_rng(seed).uniform(lo, hi, size=(n, len(ranges)))
    return [{k: float(v) for k, v in zip(ranges, row)} for row in draws]


def _file_digest(path: Path) -> str:
    """SHA-256 of a configuration file; of it and the files it extends, when it extends any."""
    try:
        chain = extends_chain(path)
    except ConfigError:
        chain = [path]  # the trial reports what is wrong with it
    digests = [hashlib.sha256(p.read_bytes()).hexdigest() for p in chain]
    return digests[0] if len(digests) == 1 else hashlib.sha256(" ".join(digests).encode()).hexdigest()


class _BaseConfigs:
    """Base configuration mappings and file digests, read once per file."""

    def __init__(self) -> None:
        self.cache: dict[tuple[str, str], dict[str, Any]] = {}
        self.digests: dict[Path, str] = {}

    def digest(self, path: Path) -> str:
        if path not in self.digests:
            found = find_config(path)  # the file a trial will load (a missing configs/NAME.yaml is the shipped one)
            self.digests[path] = _file_digest(found) if found.is_file() else "missing"
        return self.digests[path]

    def get(self, ns: str, path: Path, key: str) -> dict[str, Any]:
        ck = (ns, str(path))
        if ck not in self.cache:
            try:
                self.cache[ck] = NAMESPACES[ns].load(path)
            except ConfigError as e:
                raise SpecError(f"'{key}': cannot read the {ns} file: {e}") from None
        return self.cache[ck]


def _base_file(ns: str, plain: dict[str, tuple[str, Any]]) -> Path:
    """The file namespace ``ns`` starts from: its option's, else (the plant of a format-2 robot
    file) the plant file shipped beside that robot file, else configs/'s."""
    from wristmark.sim.setup import arm_plant_file, default_config

    file = plain.get(NAMESPACES[ns].option)
    if file:
        return Path(file[1])
    robot = plain.get(NAMESPACES["robot"].option)
    if ns == "plant" and robot:
        try:
            found = arm_plant_file(robot[1])
        except WristmarkError:
            found = None  # the trial reports what is wrong with the robot file
        if found is not None:
            return found.resolve()
    return default_config(NAMESPACES[ns].default)


def _expand(options: ExperimentOptions, fixed: dict[str, Any], points: list[dict[str, Any]],
            samples: list[dict[str, Any]], seeds: tuple[int, ...]) -> list[Trial]:
    bases = _BaseConfigs()
    trials: list[Trial] = []
    for point, sample in itertools.product(points, samples):
        values = {**point, **sample}
        assigned = {**fixed, **values}
        plain: dict[str, tuple[str, Any]] = {}  # option dest -> (key as written, value)
        dotted: list[tuple[str, str, list[str], Any]] = []
        for k, v in assigned.items():
            split = split_dotted(k)
            if split:
                dotted.append((k, split[0], split[1], v))
            else:
                dest = options.action(k).dest
                if dest in FILE_OPTIONS:
                    if not isinstance(v, str):
                        raise SpecError(f"'{k}' is a file path, got {v!r}")
                    v = str(Path(v).expanduser().resolve())
                plain[dest] = (k, v)
        configs: dict[str, dict[str, Any]] = {}
        for k, ns, parts, v in dotted:
            if ns not in configs:
                configs[ns] = bases.get(ns, _base_file(ns, plain), k)
            configs[ns] = set_dotted(configs[ns], k, parts, v)
        if "robot" in configs and "plant" not in configs and "plant" not in plain:
            # the changed robot file is written elsewhere: keep the plant shipped beside the original
            plant = _base_file("plant", plain)
            if plant != _base_file("plant", {}):
                plain["plant"] = ("plant", str(plant))
        replaced = {NAMESPACES[ns].option for ns in configs}
        inputs = {}
        for ns in NAMESPACES:
            if ns not in configs:
                inputs[ns] = bases.digest(_base_file(ns, plain))
        args = [w for dest, (k, v) in plain.items() if dest not in replaced for w in options.tokens(k, v)]
        for seed in seeds:
            trials.append(Trial(len(trials), seed, values, tuple(args), configs, inputs))
    return trials


def _validate(options: ExperimentOptions, experiment: str, trials: list[Trial]) -> None:
    """Parse and load every trial as ``wristmark experiment`` would, before any runs."""
    from wristmark.cli.experiment import check_args

    checked: set[str] = set()
    with tempfile.TemporaryDirectory(prefix="wristmark-sweep-") as tmp:
        for t in trials:
            words = write_configs(t.configs, Path(tmp) / str(t.index)) if t.configs else []
            where = f"trial {t.index}" + (" (" + ", ".join(f"{k}={format_value(v)}" for k, v in t.values.items())
                                          + ")" if t.values else "")
            try:
                args = options.parse(t.argv(experiment, words)[1:])
                key = json.dumps([list(t.args), t.configs], sort_keys=True)
                if key not in checked:
                    check_args(args)
                    checked.add(key)
            except ConfigError as e:
                msg = str(e).replace(str(Path(tmp) / str(t.index)) + "/", "")
                raise SpecError(f"{where}: {msg}") from None
