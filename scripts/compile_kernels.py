"""Compile every numba kernel of the tracker and the simulated bench's renderer once, into numba's
disk cache (the ``__pycache__`` folders beside the sources), so that later processes load them.

After a fresh install (or a change to a kernel's source) the first process that tracks or renders
compiles the kernels it runs: about a minute of CPU here. ``make test`` runs this script while
ruff and mypy run, so that the test processes (two at once, and the commands they start) load the
kernels instead of each compiling them. Its output is the seconds each part took.

    python scripts/compile_kernels.py
"""

from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path


def main() -> int:
    from wristmark.cli.main import main as wristmark
    from wristmark.cvs.tracking.warmup import warm_up

    t0 = time.perf_counter()
    warm_up()  # the tracker's kernels: grey and BGR views, both sleeves
    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        # the renderer's: the matte sleeve with sensor noise, then the glossy sleeve's laminate and motion blur
        for i, extra in enumerate(([], ["--sleeve-specular", "0.04", "--motion-blur", "2"])):
            said = io.StringIO()
            with contextlib.redirect_stdout(said):
                rc = wristmark(["render", "--out", str(Path(tmp) / str(i)), "--pairs", "1", "--image-scale", "0.25",
                                *extra])
            if rc != 0:
                print(said.getvalue(), end="")
                return rc
    print(f"compile_kernels: tracker {t1 - t0:.1f} s, renderer {time.perf_counter() - t1:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
