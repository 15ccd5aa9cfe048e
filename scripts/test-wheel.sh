#!/usr/bin/env bash
# The wheel as a user gets it: installs WHEEL into fresh venvs in a folder outside the repository
# and runs a copy of the Python test suite there, so that `import rustcloth` can only find the
# installed package (a file missing from the wheel fails a test instead of being picked up from
# the source tree).
#
#   1. The core install only, on the newest other CPython 3.12+ on the machine (NEWER_PYTHON, or
#      found on PATH and under pyenv; Python 3.11, PYTHON, only where there is none): the abi3
#      wheel on an interpreter it was not built with, and every file the package needs found in
#      the wheel. Not the whole suite: `make test` has just run it on 3.11 against an editable
#      build of the same sources, and a physics test runs the same machine code through the
#      same binding on any interpreter. What another Python can break is the binding and the
#      package, which the files in CORE_TESTS cover: every public method, property and
#      constructor with every type of argument (reliability_inputs, core_arguments,
#      hostile_input), every error (bad_input, reliability_panics), pickling and copies across
#      processes (scene_pickle, reliability_copies, sweep_local), threads around the binding's
#      lock (reliability_threads), the installed metadata, stub and data files (packaging,
#      typing), the console script and every command (cli), and each module that needs no
#      extra imported and run (scene, simulation, watchdog, garment, meshes, drivers, export,
#      reference, the sweep's). The files left out test physics, or features of an extra (2).
#   2. One fresh Python 3.11 venv per extra (export, usd, viewer, study, ray), each with only
#      `rustcloth[EXTRA]` installed, running the tests of that extra's features: an extra that
#      lacks a dependency its feature imports fails here, where installing the extras together
#      would hide it (as it hid that trimesh needs Pillow for UVs). The rest ran in 1.
#
# The runs are independent (a venv and a log each; the copy of the suite is only read), so up
# to JOBS of them (default: the number of CPUs) go at once: most of a run's time is pip
# downloading and unpacking, which overlaps with another run's tests. Each run's lines are
# printed together, in the order below, once it ends.
#
# Usage: scripts/test-wheel.sh WHEEL
#        ONLY="export usd" scripts/test-wheel.sh WHEEL   # only the runs with these labels
#        JOBS=1 scripts/test-wheel.sh WHEEL              # one run at a time
set -euo pipefail

wheel=$(realpath "$1")
repo=$(pwd)
python=${PYTHON:-$(command -v python3.11 || command -v python3)}
work=$(mktemp -d "${TMPDIR:-/tmp}/rustcloth-wheel.XXXXXX")
trap 'rm -rf "$work"' EXIT

# The suite, and the pytest settings from pyproject.toml (markers, warnings as errors).
cp -r tests "$work/tests"
find "$work/tests" \( -name '*.rs' -o -name common -o -name __pycache__ \) -prune -exec rm -rf {} +
"$python" - "$repo/pyproject.toml" "$work/pytest.ini" <<'EOF'
import sys, tomllib
opts = tomllib.load(open(sys.argv[1], "rb"))["tool"]["pytest"]["ini_options"]
with open(sys.argv[2], "w") as f:
    f.write("[pytest]\n")
    for key, value in opts.items():
        if key != "testpaths":
            f.write(f"{key} =\n" + "".join(f"    {v}\n" for v in value))
EOF

newer_python() {
    local v c
    for v in 3.14 3.13 3.12; do
        for c in "python$v" "${PYENV_ROOT:-$HOME/.pyenv}"/versions/"$v"*/bin/"python$v"; do
            if "$c" -c 'import venv' >/dev/null 2>&1; then
                command -v "$c"
                return
            fi
        done
    done
}

# run LABEL PYTHON EXTRAS [PYTEST ARGS...]: a fresh venv, the wheel (with EXTRAS) and the test
# runner, the suite (or the tests the arguments select, paths relative to the copy).
run() {
    local label=$1 py=$2 extras=$3 venv="$work/venv-$1" start
    shift 3
    local tests=("${@:-tests}")
    "$py" -m venv "$venv"
    "$venv/bin/python" -m pip install -q --upgrade pip
    start=$EPOCHREALTIME
    "$venv/bin/python" -m pip install -q "$wheel$extras"
    echo "wheel: $label: installed rustcloth$extras into a fresh venv in" \
         "$("$venv/bin/python" -c "print(f'{$EPOCHREALTIME - $start:.1f}')") s"
    "$venv/bin/python" -m pip install -q pytest hypothesis
    (
        cd "$work"
        "$venv/bin/python" - "$venv" <<'EOF'
import sys, rustcloth
where = rustcloth.__file__
assert where.startswith(sys.argv[1]), f"rustcloth imported from {where}, not the venv"
print(f"wheel: rustcloth {rustcloth.__version__} from {where} on Python {sys.version.split()[0]}")
EOF
        if ! "$venv/bin/python" -m pytest -q -m "not long" -p no:cacheprovider "${tests[@]}" \
                > "$work/$label.log" 2>&1; then
            cat "$work/$label.log"
            echo "wheel: $label: the tests failed against the installed wheel" >&2
            exit 1
        fi
        tail -n 1 "$work/$label.log" | sed "s/^/wheel: $label: /"
    )
}

# launch LABEL PYTHON EXTRAS [PYTEST ARGS...]: `run` in the background, its output kept for
# `finish`, once fewer than JOBS runs are going.
jobs_max=${JOBS:-$(nproc)}
labels=() pids=()
launch() {
    if [ -n "${ONLY:-}" ] && [[ " $ONLY " != *" $1 "* ]]; then
        return
    fi
    while (( $(jobs -rp | wc -l) >= jobs_max )); do
        sleep 0.2
    done
    ( run "$@" ) > "$work/$1.out" 2>&1 &
    labels+=("$1") pids+=($!)
}

# finish: waits for every run, prints what each printed, and fails if one failed.
finish() {
    local i failed=0
    for i in "${!pids[@]}"; do
        if ! wait "${pids[i]}"; then
            failed=1
        fi
        cat "$work/${labels[i]}.out"
    done
    return "$failed"
}

# The binding and the package on another interpreter (see 1. above for why these files).
CORE_TESTS=(
    tests/test_packaging.py tests/test_typing.py tests/test_core_arguments.py
    tests/test_reliability_inputs.py tests/test_hostile_input.py tests/test_bad_input.py
    tests/test_reliability_panics.py tests/test_reliability_copies.py
    tests/test_reliability_threads.py tests/test_scene_pickle.py tests/test_scene.py
    tests/test_simulation.py tests/test_watchdog.py tests/test_cli.py tests/test_garment.py
    tests/test_meshes.py tests/test_drivers.py tests/test_export.py tests/test_reference.py
    tests/test_sweep_spec.py tests/test_sweep_store.py tests/test_sweep_local.py
    tests/test_sweep_cli.py
    # The slowest of those files, physics or sweeps of a thousand runs rather than the binding,
    # which the files' other tests call the same way.
    --deselect tests/test_reliability_panics.py::test_grid_shapes_step_alike_at_every_thread_count
    --deselect tests/test_garment.py::test_a_garment_shows_its_front_material_outside
    --deselect tests/test_sweep_spec.py::test_runs_are_built_one_at_a_time
    --deselect tests/test_sweep_spec.py::test_run_sweep_holds_no_scene_per_run
)
newer=${NEWER_PYTHON:-$(newer_python)}
if [ -n "$newer" ]; then
    launch "py$("$newer" -c 'import sys; print(*sys.version_info[:2], sep="")')-core" "$newer" "" \
        "${CORE_TESTS[@]}"
else
    echo "wheel: no CPython 3.12 or newer on this machine; the core tests on $("$python" -V)"
    launch py311-core "$python" "" "${CORE_TESTS[@]}"
fi

# Each extra alone, and the tests of what it is for (those of another extra skip themselves).
launch export "$python" "[export]" tests/test_export.py tests/test_cli.py tests/test_packaging.py \
    tests/test_colliders.py -k "export or obj or ply or glb or mesh_file or meshes or extra"
launch usd "$python" "[usd]" tests/test_export.py tests/test_cli.py -k "usd or fps"
launch viewer "$python" "[viewer]" tests/render tests/test_camera.py
launch study "$python" "[study]" tests/test_accuracy.py
# One small sweep on a local Ray cluster started by the test (two CPUs).
launch ray "$python" "[ray]" tests/test_sweep_ray.py -k bitwise
finish
