"""A CasADi Function compiled to C and called through ctypes: :class:`CompiledFunction`.

CasADi's own evaluation (its virtual machine, ``Function.buffer()``) holds Python's interpreter
lock for the whole call, so the pose solves of cvs.tracking.arm_set's threads ran one after the
other. The same Function's generated C, compiled without fast math and without contracting
products and sums into fused multiply-adds, does the same IEEE operations in the same order: its
outputs are the virtual machine's to the last bit (tests/cvs/tracking/test_compiled_function.py),
about 8 times faster, and ctypes releases the lock for the call.

A library is built once per function and kept in a cache directory (``WRISTMARK_CACHE``, else
``$XDG_CACHE_HOME/wristmark``, else ``~/.cache/wristmark``): compiling the pose solve takes ~40 s,
so it is never done on the way to a frame: ``python -m wristmark.cvs.tracking.compiled_pose``
(``make setup``) builds it, and a solver whose library is not there uses CasADi's evaluation.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError

__all__ = ["CFLAGS", "CompiledFunction", "build", "cache_dir", "library_path", "load"]

CFLAGS = ("-O1", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math")


def cache_dir() -> Path:
    """Where compiled functions are kept (``WRISTMARK_CACHE``, else the user's cache directory)."""
    env = os.environ.get("WRISTMARK_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "wristmark"


def library_path(function: ca.Function, key: str) -> Path:
    """The cached library of ``function`` under ``key`` (a digest of everything it is built from;
    the CasADi version and :data:`CFLAGS` are added here)."""
    digest = hashlib.sha256("|".join([key, str(getattr(ca, "__version__", "")), *CFLAGS]).encode()).hexdigest()[:16]
    return cache_dir() / f"{function.name()}-{digest}.so"


def build(function: ca.Function, key: str) -> Path:
    """Generate ``function``'s C, compile it (``cc``, :data:`CFLAGS`) into the cache and return
    the library's path (kept when already there). Raises InputError when no C compiler is found
    or compiling fails."""
    out = library_path(function, key)
    if out.exists():
        return out
    cc = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if cc is None:
        raise InputError("no C compiler (cc or gcc) to compile the pose solve with")
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        src = Path(tmp) / f"{function.name()}.c"
        gen = ca.CodeGenerator(src.name, {"with_header": False})
        gen.add(function)
        gen.generate(tmp + os.sep)
        lib = Path(tmp) / out.name
        run = subprocess.run([cc, *CFLAGS, str(src), "-o", str(lib), "-lm"], capture_output=True, text=True)
        if run.returncode != 0:
            raise InputError(f"compiling {function.name()} failed: {run.stderr.strip().splitlines()[-1:]}")
        os.replace(lib, out)  # atomic: a concurrent build leaves one whole library
    return out


class CompiledFunction:
    """A one-input, one-output dense CasADi Function's compiled code bound to an input and an
    output buffer (float64, the Function's sizes): ``f()`` evaluates it, as ``Function.buffer()``'s
    eval does, without holding the interpreter lock. One call at a time per instance."""

    def __init__(self, path: Path, function: ca.Function, inp: NDArray[np.float64], out: NDArray[np.float64]) -> None:
        if function.n_in() != 1 or function.n_out() != 1 or inp.size != function.nnz_in(0) or \
                out.size != function.nnz_out(0) or inp.dtype != np.float64 or out.dtype != np.float64:
            raise InputError(f"{function.name()}: one dense float64 input and output of its sizes needed")
        lib = ctypes.CDLL(str(path))
        self._fn = getattr(lib, function.name())
        self._fn.restype = ctypes.c_int
        self._fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int]
        self._lib, self._inp, self._out = lib, inp, out  # kept alive with the pointers below
        self._w = np.zeros(max(1, function.sz_w()))
        self._iw = np.zeros(max(1, function.sz_iw()), np.int64)
        args = (ctypes.c_void_p * max(1, function.sz_arg()))()
        res = (ctypes.c_void_p * max(1, function.sz_res()))()
        args[0], res[0] = inp.ctypes.data, out.ctypes.data
        self._call = (args, res, self._iw.ctypes.data, self._w.ctypes.data, 0)

    def __call__(self) -> None:
        if self._fn(*self._call) != 0:
            raise RuntimeError("compiled CasADi function failed")


def load(function: ca.Function, key: str, inp: NDArray[np.float64], out: NDArray[np.float64]
         ) -> CompiledFunction | None:
    """``function``'s compiled code bound to ``inp`` / ``out`` when its library is in the cache
    (:func:`build`), else None (the caller evaluates with CasADi)."""
    path = library_path(function, key)
    if not path.exists():
        return None
    try:
        return CompiledFunction(path, function, inp, out)
    except OSError:  # a library from another machine or a broken file: CasADi evaluates
        return None
