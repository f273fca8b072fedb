#!/usr/bin/env bash
# Installs what `wristmark render --engine pbr` needs: Debian's libllvm19 (Mitsuba's CPU variant
# llvm_ad_rgb needs LLVM >= 19; 14/15 fail with "Cannot select fminimum") and the extra 'pbr'
# (mitsuba 3 from PyPI) into the Python given as $PYTHON (default: the project's .venv, made by
# `make setup`, else python3).
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
if [ -x "$HERE/.venv/bin/python" ]; then DEFAULT_PY="$HERE/.venv/bin/python"; else DEFAULT_PY=python3; fi
PY="${PYTHON:-$DEFAULT_PY}"
LIB=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
if [ ! -e "$LIB" ] && [ ! -e /usr/lib/llvm-19/lib/libLLVM.so.1 ]; then
  SUDO=""
  if [ "$(id -u)" != "0" ]; then SUDO="sudo"; fi
  echo "installing Debian libllvm19 for Mitsuba's CPU variant..." >&2
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq >/dev/null
  $SUDO apt-get install -y -qq --no-install-recommends libllvm19 >/dev/null
fi
if ! "$PY" -c "import mitsuba" >/dev/null 2>&1; then
  "$PY" -m pip install -q 'mitsuba>=3.9,<4'
fi
DRJIT_LIBLLVM_PATH="${DRJIT_LIBLLVM_PATH:-$LIB}" "$PY" -c "import mitsuba as mi; mi.set_variant('llvm_ad_rgb')"
