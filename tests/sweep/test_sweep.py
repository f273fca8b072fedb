"""`wristmark sweep` as a user runs it: 6 short truth-noise trials on a LocalCluster of 2 workers
agree exactly with 1 worker and with the same runs of `wristmark experiment`; a sweep killed
part way resumes with only the missing trials; a bad SPEC is one line before any trial starts."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import yaml

from wristmark.cli.main import main
from wristmark.models.config_files import CONFIG_DIR

ROOT = Path(__file__).resolve().parents[2]
METRICS = ("open_mean_mm", "open_max_mm", "closed_mean_mm", "closed_max_mm", "ratio", "closed_rms_mm",
           "closed_p95_mm", "lost", "rejected")
LATENCY = (0.03, 0.045, 0.05)
BACKLASH = (0.0, 0.012)
SEED = 5
TENDON3 = ROOT / "configs" / "robots" / "tendon3.yaml"
SPEC = {
    "experiment": "cube",
    "set": {"sensor": "truth-noise", "duration": 1.5, "rig.settle_time": 0.5},
    "grid": {"latency": list(LATENCY), "plant.backlash.0": list(BACKLASH)},
    "seeds": [SEED],
}


def wristmark(*args: str, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "wristmark", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def write_yaml(path: Path, data: dict) -> None:
    path.write_text(yaml.safe_dump(data, sort_keys=False))


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def metric_rows(path: Path) -> list[tuple[str, ...]]:
    """trial, seed, swept values and metrics of every row: everything but wall time and worker."""
    return [tuple(r[k] for k in ("trial", "seed", "latency", "plant.backlash.0", *METRICS, "status"))
            for r in rows(path)]


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("spec") / "sweep.yaml"
    write_yaml(p, SPEC)
    return p


@pytest.fixture(scope="module")
def two_workers(spec_file: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("w2") / "sweep"
    r = wristmark("sweep", str(spec_file), "--out", str(out), "--workers", "2", "--no-progress")
    assert r.returncode == 0, r.stderr
    assert "closed mean [mm]" in r.stdout  # the summary table
    return out


@pytest.mark.slow
@pytest.mark.network
def test_results_csv_has_the_documented_header_and_one_ordered_row_per_trial(two_workers: Path) -> None:
    with open(two_workers / "results.csv", newline="") as f:
        header = next(csv.reader(f))
    assert header[:4] == ["trial", "seed", "latency", "plant.backlash.0"]
    assert header[-3:] == ["status", "wall_s", "worker"]
    for k in ("open_mean_mm", "open_max_mm", "closed_mean_mm", "closed_max_mm", "ratio"):
        assert k in header
    got = rows(two_workers / "results.csv")
    assert [r["trial"] for r in got] == [str(i) for i in range(6)]
    assert [(float(r["latency"]), float(r["plant.backlash.0"])) for r in got] == \
        [(lat, b) for lat in LATENCY for b in BACKLASH]  # first grid key varies slowest
    assert all(r["status"] == "ok" and r["seed"] == str(SEED) for r in got)
    assert len({r["worker"] for r in got}) == 2  # both workers ran trials
    assert all(float(r["wall_s"]) > 0 for r in got)
    # backlash on the stem rotation makes the open loop worse, and the loop still removes most of it
    by = {(float(r["latency"]), float(r["plant.backlash.0"])): r for r in got}
    assert float(by[(0.03, 0.012)]["open_mean_mm"]) > float(by[(0.03, 0.0)]["open_mean_mm"])
    assert all(float(r["ratio"]) < 0.5 for r in got)
    summary = (two_workers / "summary.md").read_text()
    assert "| latency | plant.backlash.0 |" in summary
    pngs = {p.name for p in (two_workers / "plots").glob("*.png")}
    assert {"metrics_vs_latency.png", "metrics_vs_plant_backlash_0.png",
            "heatmap_latency_plant_backlash_0.png"} <= pngs
    for name in pngs:
        assert f"plots/{name}" in summary


@pytest.mark.slow
@pytest.mark.network
def test_one_worker_gives_exactly_the_same_rows(spec_file: Path, two_workers: Path, tmp_path: Path) -> None:
    out = tmp_path / "w1"
    r = wristmark("sweep", str(spec_file), "--out", str(out), "--workers", "1", "--no-progress")
    assert r.returncode == 0, r.stderr
    assert len({row["worker"] for row in rows(out / "results.csv")}) == 1
    assert metric_rows(out / "results.csv") == metric_rows(two_workers / "results.csv")


@pytest.mark.slow
@pytest.mark.network
def test_trials_equal_the_same_runs_of_wristmark_experiment(two_workers: Path, tmp_path: Path) -> None:
    """Each trial run by hand: plant and rig files written here from configs/, not by the sweep."""
    base = yaml.safe_load((CONFIG_DIR / "plant.yaml").read_text())
    rig = yaml.safe_load((CONFIG_DIR / "rig.yaml").read_text())
    rig["loop"]["settle_time"] = 0.5
    write_yaml(tmp_path / "rig.yaml", rig)

    def one(i: int, latency: float, backlash: float) -> dict:
        plant = dict(base, backlash=[backlash, *base["backlash"][1:]])
        write_yaml(tmp_path / f"plant{i}.yaml", plant)
        r = wristmark("experiment", "cube", "--sensor", "truth-noise", "--duration", "1.5", "--latency", str(latency),
                      "--rig", str(tmp_path / "rig.yaml"),
                      "--plant", str(tmp_path / f"plant{i}.yaml"), "--seed", str(SEED), "--no-progress",
                      "--out", str(tmp_path / f"run{i}"), "--json", str(tmp_path / f"res{i}.json"))
        assert r.returncode == 0, r.stderr
        return json.loads((tmp_path / f"res{i}.json").read_text())

    points = [(lat, b) for lat in LATENCY for b in BACKLASH]
    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(one, range(6), *zip(*points)))
    for row, res in zip(rows(two_workers / "results.csv"), results):
        o, c = res["open_loop"], res["closed_loop"]
        expected = {"open_mean_mm": o["mean_mm"], "open_max_mm": o["max_mm"], "closed_mean_mm": c["mean_mm"],
                    "closed_max_mm": c["max_mm"], "ratio": res["ratio"], "closed_rms_mm": c["rms_mm"],
                    "closed_p95_mm": c["p95_mm"], "lost": c["lost"], "rejected": c["rejected"]}
        assert {k: float(row[k]) for k in expected} == expected, row["trial"]  # exactly, not approximately


@pytest.mark.slow
@pytest.mark.network
def test_a_killed_sweep_resumes_with_only_the_missing_trials(spec_file: Path, two_workers: Path,
                                                            tmp_path: Path) -> None:
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "wristmark", "sweep", str(spec_file), "--out", str(out),
                             "--workers", "1", "--no-progress"], cwd=ROOT, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and proc.poll() is None:
            if (out / "results.csv").is_file() and len(rows(out / "results.csv")) >= 2:
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the sweep ended before it could be killed"
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its workers, as a crash would
        proc.wait(timeout=30)
    killed_at = time.time()
    before = {r["trial"]: r for r in rows(out / "results.csv")}
    assert 2 <= len(before) < 6
    r = wristmark("sweep", str(spec_file), "--out", str(out), "--workers", "2", "--no-progress")
    assert r.returncode == 0, r.stderr
    assert f"resuming: {len(before)} of 6 trials" in r.stderr
    after = rows(out / "results.csv")
    assert [row["trial"] for row in after] == [str(i) for i in range(6)]
    new_workers = set()
    for row in after:
        if row["trial"] in before:  # kept as it was: same wall time, same (now gone) worker
            assert row == before[row["trial"]]
            res = out / "trials" / f"{int(row['trial']):04d}" / "result.json"
            assert res.stat().st_mtime < killed_at  # not run again
        else:
            new_workers.add(row["worker"])
    assert new_workers and not new_workers & {b["worker"] for b in before.values()}  # only the missing ran now
    assert metric_rows(out / "results.csv") == metric_rows(two_workers / "results.csv")


@pytest.mark.slow
@pytest.mark.network
def test_another_spec_in_the_same_folder_is_refused(two_workers: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    other = tmp_path / "other.yaml"
    write_yaml(other, {**SPEC, "seeds": [SEED + 1]})
    before = (two_workers / "results.csv").read_text()
    assert main(["sweep", str(other), "--out", str(two_workers), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "different sweep" in err[0]
    assert (two_workers / "results.csv").read_text() == before
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    assert main(["sweep", str(other), "--out", str(tmp_path / "busy"), "--no-progress"]) == 2
    assert "holds no sweep" in capsys.readouterr().err


BAD_SPECS = [
    ({"experiment": "cube", "grid": {"latncy": [0.03]}}, ["unknown key 'latncy'", "latency"]),
    ({"experiment": "cube", "grid": {}}, ["'grid' is empty"]),
    ({"experiment": "cube", "grid": {"latency": []}}, ["grid.latency", "non-empty list"]),
    ({"experiment": "cube", "grid": {"plant.backlsh.0": [0.0]}}, ["plant.backlsh.0", "backlash"]),
    ({"experiment": "cube", "grid": {"plant.backlash.6": [0.0]}}, ["plant.backlash.6", "list of 6"]),
    ({"experiment": "cube", "grid": {"rigg.gate": [0.01]}}, ["rigg.gate", "plant, rig, controller"]),
    ({"experiment": "cube", "grid": {"latency": ["fast"]}}, ["--latency", "'fast' is not a number"]),
    ({"experiment": "cube", "grid": {"plant.backlash.0": ["wide"]}}, ["backlash[0]", "must be a number"]),
    ({"experiment": "cube", "grid": {"rig.max_lost_cycles": [2.5]}}, ["max_lost_cycles", "integer"]),
    ({"experiment": "cube", "grid": {"latency": [float("nan")]}}, ["grid.latency", "nan", "finite"]),
    ({"experiment": "cube", "random": {"n": 2, "ranges": {"plant.bend_gain.0": [0.9, float("nan")]}}},
     ["plant.bend_gain.0", "finite"]),
    ({"experiment": "cube", "grid": {"latency": [0.07]}}, ["vision_latency", "control_dt"]),
    ({"experiment": "cube", "set": {"seed": 3}}, ["'seed'", "seeds"]),
    ({"experiment": "cube", "seeds": [1.5]}, ["seeds", "integer"]),
    ({"experiment": "cubes"}, ["'experiment'", "cube, point, accuracy, load"]),
    ({"experiment": "cube", "grids": {"latency": [0.03]}}, ["unknown top-level key 'grids'"]),
    ({"experiment": "cube", "set": {"robot": str(TENDON3)}, "grid": {"robot.segments.3.length": [0.01]}},
     ["robot.segments.3.length", "list of 3"]),
    ({"experiment": "cube", "set": {"robot": str(TENDON3)}, "grid": {"robot.segments.0.lenght": [0.01]}},
     ["robot.segments.0.lenght", "length"]),
    ({"experiment": "cube", "set": {"robot": str(TENDON3)}, "grid": {"robot.segments.0.length": [-0.01]}},
     ["trial 0", "segments[0].length", "expected > 0"]),
]


@pytest.mark.parametrize(("spec", "words"), BAD_SPECS, ids=[w[0] for _, w in BAD_SPECS])
def test_a_bad_spec_is_one_line_before_any_trial(spec: dict, words: list[str], tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.yaml"
    write_yaml(path, spec)
    assert main(["sweep", str(path), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("wristmark sweep: error: ")
    for w in words:
        assert w in lines[0], lines[0]
    assert not (tmp_path / "out").exists()  # nothing started


def test_a_bad_spec_from_the_console_exits_2_without_a_traceback(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("experiment: cube\ngrid: {plant.nothing: [1.0]}\n")
    r = wristmark("sweep", str(path), "--out", str(tmp_path / "out"), timeout=60)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "plant.nothing" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.network
def test_a_safe_stop_and_an_error_are_rows_not_a_crashed_sweep(tmp_path: Path) -> None:
    spec = tmp_path / "fail.yaml"
    write_yaml(spec, {
        "experiment": "point",
        "set": {"sensor": "truth-noise", "duration": 1.0, "rig.max_lost_cycles": 3},
        "grid": {"rig.model_gate": [0.025, 1e-6]},
    })
    r = wristmark("sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "--no-progress")
    assert r.returncode == 0, r.stderr
    ok, stopped = rows(tmp_path / "out" / "results.csv")
    assert ok["status"] == "ok" and float(ok["closed_mean_mm"]) < float(ok["open_mean_mm"])
    assert stopped["status"].startswith("stopped: marker lost") and stopped["closed_mean_mm"] == ""
    assert "1 of 2 trials did not finish ok" in r.stderr
    assert "stopped: marker lost" in (tmp_path / "out" / "summary.md").read_text()


def test_a_trial_that_fails_returns_an_error_row(tmp_path: Path) -> None:
    from wristmark.sweep.spec import load_spec
    from wristmark.sweep.trial import TrialJob, run_trial

    spec = tmp_path / "far.yaml"
    write_yaml(spec, {"experiment": "point", "set": {"sensor": "truth-noise", "duration": 1.0},
                      "grid": {"point": [[0.0, 0.0, 0.5]]}})
    s = load_spec(spec)
    row = run_trial(TrialJob(s.experiment, s.trials[0], str(tmp_path / "t0")))
    assert row["status"].startswith("error: the point [0.0, 0.0, 500.0] mm is out of reach")
    assert "\n" not in row["status"] and row["worker"] == "local"
    assert "open_mean_mm" not in row
    command = (tmp_path / "t0" / "command.txt").read_text()
    assert command.startswith("wristmark experiment point ") and "--point 0.0 0.0 0.5" in command


def test_trials_expand_grid_random_and_seeds_in_order(tmp_path: Path) -> None:
    from wristmark.sweep.spec import load_spec

    spec = tmp_path / "mix.yaml"
    write_yaml(spec, {
        "experiment": "cube", "set": {"sensor": "truth-noise", "controller.kp": 6.0},
        "grid": {"controller": ["qp", "paper"]},
        "random": {"n": 3, "seed": 11, "ranges": {"plant.bend_gain.0": [0.9, 1.1], "dt": [0.05, 0.07]}},
        "seeds": [0, 1],
    })
    s = load_spec(spec)
    again = load_spec(spec)
    assert len(s.trials) == 2 * 3 * 2
    assert s.swept_keys == ["controller", "plant.bend_gain.0", "dt"]
    assert [t.seed for t in s.trials] == [0, 1] * 6
    assert [t.values["controller"] for t in s.trials] == ["qp"] * 6 + ["paper"] * 6
    gains = [t.values["plant.bend_gain.0"] for t in s.trials]
    assert gains == [t.values["plant.bend_gain.0"] for t in again.trials]  # seeded
    assert len(set(gains)) == 3 and all(0.9 <= g <= 1.1 for g in gains)
    assert gains[:6] == gains[6:]  # the same samples at every grid point
    t = s.trials[0]
    assert t.configs["controller"]["kp"] == 6.0 and t.configs["plant"]["bend_gain"][0] == gains[0]
    assert "--controller" in t.args and "--dt" in t.args and "--plant" not in t.args
    assert s.fingerprint() == again.fingerprint()


@pytest.mark.slow
@pytest.mark.network
def test_the_same_sweep_runs_on_an_existing_cluster(two_workers: Path, tmp_path: Path) -> None:
    """`dask scheduler` + `dask worker` started here (127.0.0.1, OS-chosen port), then --scheduler."""
    dask = str(Path(sys.executable).with_name("dask"))
    info = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(info)], cwd=tmp_path, start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        procs.append(subprocess.Popen([dask, "worker", "--scheduler-file", str(info), "--host", "127.0.0.1",
                                       "--nworkers", "1", "--nthreads", "1", "--no-dashboard"], cwd=tmp_path,
                                      start_new_session=True, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
        deadline = time.monotonic() + 60
        while not info.is_file() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        spec = tmp_path / "part.yaml"
        write_yaml(spec, {**SPEC, "grid": {"latency": [LATENCY[0]], "plant.backlash.0": list(BACKLASH)}})
        r = wristmark("sweep", str(spec), "--out", str(tmp_path / "out"), "--scheduler", address, "--no-progress")
        assert r.returncode == 0, r.stderr
    finally:
        for p in reversed(procs):
            os.killpg(p.pid, signal.SIGTERM)
            p.wait(timeout=30)
    got = metric_rows(tmp_path / "out" / "results.csv")
    assert got == metric_rows(two_workers / "results.csv")[:2]  # trials 0, 1 of the full sweep
    workers = {row["worker"] for row in rows(tmp_path / "out" / "results.csv")}
    assert len(workers) == 1 and workers != {"local"}


@pytest.mark.slow
@pytest.mark.network
def test_an_unreachable_scheduler_is_one_line(tmp_path: Path, spec_file: Path) -> None:
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    r = wristmark("sweep", str(spec_file), "--out", str(tmp_path / "out"), "--scheduler",
                  f"tcp://127.0.0.1:{port}", "--no-progress", timeout=120)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "cannot reach the dask scheduler" in r.stderr, r.stderr


def test_the_fingerprint_follows_the_configuration_files_a_trial_reads(tmp_path: Path) -> None:
    from wristmark.sweep.spec import load_spec

    plant = tmp_path / "plant.yaml"
    plant.write_text((CONFIG_DIR / "plant.yaml").read_text())
    spec = tmp_path / "s.yaml"
    write_yaml(spec, {"experiment": "cube", "set": {"sensor": "truth-noise", "plant": str(plant)},
                      "grid": {"latency": [0.03, 0.04]}})
    first = load_spec(spec).fingerprint()
    assert load_spec(spec).fingerprint() == first
    plant.write_text(plant.read_text().replace("actuator_tau: 0.04", "actuator_tau: 0.05"))
    assert load_spec(spec).fingerprint() != first  # a resumed sweep would otherwise mix two plants


@pytest.mark.slow
def test_robot_keys_of_a_format2_robot_file_sweep_its_segments(tmp_path: Path) -> None:
    spec = tmp_path / "arm.yaml"
    write_yaml(spec, {"experiment": "cube",
                      "set": {"sensor": "truth-noise", "duration": 0.3, "rig.settle_time": 0.2, "robot": str(TENDON3)},
                      "grid": {"robot.segments.0.length": [0.038, 0.042]}})
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    got = rows(out / "results.csv")
    assert [r["robot.segments.0.length"] for r in got] == ["0.038", "0.042"]
    assert all(r["status"] == "ok" and float(r["closed_mean_mm"]) > 0 for r in got), got
    for r, length in zip(got, (0.038, 0.042)):
        trial = out / "trials" / f"{int(r['trial']):04d}"
        robot = yaml.safe_load((trial / "config" / "robot.yaml").read_text())
        assert robot["format"] == 2 and robot["segments"][0]["length"] == length and len(robot["segments"]) == 3
        assert "tip_offset" not in robot  # the marker file's
        # the changed file is written elsewhere: the trial keeps the plant shipped beside tendon3.yaml
        assert "robots/tendon3_plant.yaml" in (trial / "command.txt").read_text()
        assert json.loads((trial / "run" / "result.json").read_text())["arm"]["name"] == "tendon3"


@pytest.mark.slow
@pytest.mark.parametrize(("experiment", "options", "filled"), [
    ("accuracy", {"positions": 3}, ("accuracy_mean_mm", "accuracy_max_mm", "tracked")),
    ("load", {"forces": [0.0, 0.2], "duration": 0.6, "rig.settle_time": 0.3},
     ("open_mean_mm", "open_max_mm", "closed_mean_mm", "closed_max_mm", "ratio")),
])
def test_accuracy_and_load_trials_fill_their_metrics(experiment: str, options: dict, filled: tuple[str, ...],
                                                     tmp_path: Path) -> None:
    from wristmark.sweep.spec import load_spec
    from wristmark.sweep.trial import TrialJob, metric_columns, run_trial

    spec = tmp_path / "s.yaml"
    write_yaml(spec, {"experiment": experiment, "set": {"sensor": "truth-noise", **options}})
    s = load_spec(spec)
    row = run_trial(TrialJob(s.experiment, s.trials[0], str(tmp_path / "t0")))
    assert row["status"] == "ok", row
    assert set(filled) <= set(metric_columns(experiment))
    assert all(row[k] >= 0 for k in filled)
    res = json.loads((tmp_path / "t0" / "result.json").read_text())
    if experiment == "accuracy":
        assert row["accuracy_mean_mm"] == res["mean_mm"] and row["tracked"] == 3
    else:  # the mean over the forces of the means, the largest max
        assert row["closed_mean_mm"] == sum(r["closed_loop"]["mean_mm"] for r in res["rows"]) / 2
        assert row["open_max_mm"] == max(r["open_loop"]["max_mm"] for r in res["rows"])


_PIN_AFTER_NUMBA = """
import numba
numba.get_num_threads()  # numba's pool started at its default size, as in a process that already ran kernels
from wristmark.sweep.trial import pin_threads
pin_threads()
@numba.njit
def one_more(x):
    return x + 1
print(one_more(1), numba.get_num_threads())
"""


def test_pinning_a_process_whose_numba_pool_started_keeps_numba_compiling() -> None:
    """A trial run in an existing process (tests, an in-process sweep) pins its threads without
    breaking numba: NUMBA_NUM_THREADS changed under a started pool made the next compilation
    raise RuntimeError ('Cannot set NUMBA_NUM_THREADS ... once the threads have been launched')."""
    r = subprocess.run([sys.executable, "-c", _PIN_AFTER_NUMBA], capture_output=True, text=True, timeout=300,
                       cwd=ROOT)
    assert r.returncode == 0, r.stderr[-500:]
    assert r.stdout.split() == ["2", "1"]  # compiled and ran; numba held to one thread
