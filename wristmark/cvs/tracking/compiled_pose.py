"""Build the compiled stereo pose solve (cvs.tracking.compiled_function) for the tracker's settings.

``python -m wristmark.cvs.tracking.compiled_pose [COLUMNS ...]`` (``make setup`` runs it; ~40 s
per marker layout) compiles the solve of the default pose settings for markers of so many
columns (default: every marker file under configs/). Without it every solver works, slower,
with CasADi's own evaluation.
"""

from __future__ import annotations

import sys
from pathlib import Path

from wristmark.cvs.tracking.compiled_function import build
from wristmark.cvs.tracking.stereo_pose import PoseSettings, build_pose_function, pose_function_key

__all__ = ["build_pose_solve"]


def build_pose_solve(columns: int, settings: PoseSettings | None = None) -> Path:
    """Compile (or find in the cache) the pose solve for markers of ``columns`` columns."""
    s = settings or PoseSettings()
    return build(build_pose_function(columns, s.steps, s.lm_lambda), pose_function_key(columns, s.steps, s.lm_lambda))


def _config_columns() -> list[int]:
    """Every marker layout's column count under configs/ (the repository's, where run from it)."""
    from wristmark.models.marker import MarkerModel

    out: set[int] = set()
    for p in sorted(Path("configs").glob("**/*.yaml")):
        if "columns:" not in p.read_text():
            continue
        try:
            out.add(MarkerModel.load(p).columns)
        except Exception:  # not a marker file
            continue
    return sorted(out) or [12]


def main(argv: list[str]) -> int:
    cols = [int(a) for a in argv] or _config_columns()
    for c in cols:
        print(f"compiled pose solve, {c} columns: {build_pose_solve(c)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
