#!/usr/bin/env bash
# Creates /work/main/.venv-peers (next to this repository: <repo>/.venv-peers) with pinned peers
# for benches/peers/run.py and contact.py: newton (NVIDIA, on Warp, CPU device), Taichi, numpy, and rustcloth
# itself built from this repository (maturin, release profile: a few minutes the first time).
# Idempotent: a venv that already has every pin and rustcloth is left alone; FORCE=1 rebuilds
# rustcloth (e.g. after changing the Rust code).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
VENV="${PEERS_VENV:-$ROOT/.venv-peers}"  # PEERS_VENV: elsewhere (testing this script)
PYTHON="${PYTHON:-$(command -v python3.11 || command -v python3)}"

# Pins checked on Python 3.11 / x86_64 Linux / no GPU (2026-11-24).
PINS=(
    "numpy==2.4.6"
    "newton==1.8.0"
    "warp-lang==1.19.0"
    "taichi==1.7.4"
    "usd-core==26.11"  # pxr: newton's example_cloth_twist reads warp's square_cloth.usd
)

if [[ ! -x "$VENV/bin/python" ]]; then
    "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install -q --upgrade pip
fi

if ! "$VENV/bin/python" - "${PINS[@]}" <<'PY'
import sys
from importlib.metadata import PackageNotFoundError, version
for pin in sys.argv[1:]:
    name, want = pin.split("==")
    try:
        if version(name) != want:
            sys.exit(1)
    except PackageNotFoundError:
        sys.exit(1)
PY
then
    "$VENV/bin/python" -m pip install -q "${PINS[@]}"
fi

# rustcloth from the working tree. A separate cargo target dir keeps this build (its own
# Python interpreter, isolated build env) from invalidating the development build in target/.
if [[ "${FORCE:-0}" == 1 ]]; then
    echo "rebuilding rustcloth into $VENV (release, a few minutes)..."
    CARGO_TARGET_DIR="$VENV/cargo-target" "$VENV/bin/python" -m pip install -q --force-reinstall \
        --no-deps "$ROOT"
elif ! (cd / && "$VENV/bin/python" -c "import rustcloth") 2>/dev/null; then
    echo "building rustcloth into $VENV (release, a few minutes)..."
    CARGO_TARGET_DIR="$VENV/cargo-target" "$VENV/bin/python" -m pip install -q "$ROOT" "${PINS[@]}"
fi

(cd / && "$VENV/bin/python" -c "
import numpy, newton, warp, taichi, rustcloth
print('peers venv ready:', 'numpy', numpy.__version__, '| newton', newton.__version__,
      '| warp', warp.__version__, '| taichi', '.'.join(map(str, taichi.__version__)),
      '| rustcloth', rustcloth.__file__)
" 2>&1 | grep -v '^\[Taichi\]')
