#!/usr/bin/env bash
# Vendor clients against `vatcal sim-cell`: mecademicpy 3.0.3 and zaber-motion 10.2.0 (from PyPI,
# in a virtual environment of their own) drive the simulated Meca500 and Zaber guide unchanged.
#
#   scripts/interop/run.sh [PATH/TO/vatcal]     (default: target/debug/vatcal, built if missing)
#
# The venv lives in target/interop-venv (override with VATCAL_INTEROP_VENV). Exit 0 = both
# clients passed every step; the Python script prints one line per step.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"

bin="${1:-$root/target/debug/vatcal}"
if [ ! -x "$bin" ]; then
    if [ $# -ge 1 ]; then
        echo "interop: no vatcal binary at $bin" >&2
        exit 2
    fi
    (cd "$root" && cargo build -p vatcal-cli --bin vatcal)
fi

if ! command -v python3 >/dev/null 2>&1; then
    echo "interop: python3 is required" >&2
    exit 2
fi
venv="${VATCAL_INTEROP_VENV:-$root/target/interop-venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    "mecademicpy==3.0.3" "zaber-motion==10.2.0"

exec "$venv/bin/python" "$here/interop.py" "$bin"
