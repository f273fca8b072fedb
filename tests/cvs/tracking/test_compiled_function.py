"""The pose solve compiled to C (cvs.tracking.compiled_function): the same outputs as CasADi's
own evaluation to the last bit, used by the solver when built, never built on the way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.compiled_function import build, library_path, load
from wristmark.cvs.tracking.compiled_pose import build_pose_solve
from wristmark.cvs.tracking.stereo_pose import PoseSettings, StereoPoseSolver, build_pose_function, pose_function_key
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.marker import MarkerModel

CAM = load_calibration(CONFIG_DIR / "camera.yaml")
SMALL = PoseSettings(steps=1)  # a solve that compiles in seconds; the default takes ~40 s


@pytest.fixture()
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("WRISTMARK_CACHE", str(tmp_path))
    return tmp_path


def _observations(solver: StereoPoseSolver, rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    T[:3, 3] = [rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01), rng.uniform(0.08, 0.11)]
    idx = np.arange(n)
    P = solver.marker_points(idx) @ T[:3, :3].T + T[:3, 3]
    uv_l = CAM.left.project(P) + rng.normal(0, 0.3, (n, 2))
    uv_r = CAM.right.project(P @ np.asarray(CAM.R).T + np.asarray(CAM.T).reshape(3)) + rng.normal(0, 0.3, (n, 2))
    T0 = T.copy()
    T0[:3, 3] += rng.normal(0, 0.002, 3)
    return idx, uv_l, uv_r, T0


def test_the_compiled_solve_gives_casadis_outputs_to_the_last_bit(cache: Path) -> None:
    marker = MarkerModel()
    vm = StereoPoseSolver(CAM, marker, SMALL)
    assert vm.compiled is None  # not built: CasADi evaluates, nothing compiled on the way
    path = build_pose_solve(marker.columns, SMALL)
    assert path.parent == cache and path.exists()
    fast = StereoPoseSolver(CAM, marker, SMALL)
    assert fast.compiled is not None
    rng = np.random.default_rng(3)
    rejected = 0
    for n in (3, 5, 8, marker.columns):
        idx, uv_l, uv_r, T0 = _observations(vm, rng, n)
        uv_l[0] += 6.0  # an outlier: the rejection rounds re-solve with it weighted out
        a, b = vm.solve(idx, uv_l, idx, uv_r, T0), fast.solve(idx, uv_l, idx, uv_r, T0)
        assert np.array_equal(a.T_fit, b.T_fit) and a.rms_px == b.rms_px
        assert np.array_equal(a.inliers_left, b.inliers_left) and np.array_equal(a.inliers_right, b.inliers_right)
        rejected += int(not a.inliers_left.all())
    assert rejected > 0  # the rejection rounds ran too


def test_a_library_is_keyed_by_what_the_solve_is_built_from(cache: Path) -> None:
    f = build_pose_function(12, SMALL.steps, SMALL.lm_lambda)
    keys = {pose_function_key(12, 1, 1e-4), pose_function_key(12, 2, 1e-4), pose_function_key(8, 1, 1e-4),
            pose_function_key(12, 1, 1e-3)}
    assert len(keys) == 4 and len({library_path(f, k) for k in keys}) == 4


def test_a_broken_library_is_not_used(cache: Path) -> None:
    f = build_pose_function(12, SMALL.steps, SMALL.lm_lambda)
    key = pose_function_key(12, SMALL.steps, SMALL.lm_lambda)
    library_path(f, key).write_bytes(b"not a library")
    inp, out = np.zeros(f.nnz_in(0)), np.zeros(f.nnz_out(0))
    assert load(f, key, inp, out) is None
    assert StereoPoseSolver(CAM, MarkerModel(), SMALL).compiled is None


def test_building_again_keeps_the_library(cache: Path) -> None:
    f = build_pose_function(4, 1, 1e-4)
    path = build(f, "k")
    stamp = path.stat().st_mtime_ns
    assert build(f, "k") == path and path.stat().st_mtime_ns == stamp
