# One entry point for every chore. `make demo` and `make test` set everything up on a fresh
# Debian machine with Rust and Python 3.11: Debian packages (as root), the virtualenv, the build.

SHELL := bash
.SHELLFLAGS := -eu -o pipefail -c
export PATH := $(HOME)/.cargo/bin:$(PATH)

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
RUST_SOURCES := $(shell find src benches -name '*.rs') Cargo.toml Cargo.lock $(wildcard scenes/*.toml)

# The files a wheel is made of: a change to any of them rebuilds it.
PY_SOURCES := $(shell find python -type f -not -name '*.so' -not -path '*/__pycache__/*')
WHEEL_INPUTS := $(RUST_SOURCES) $(PY_SOURCES) pyproject.toml README.md LICENSE
# The oldest glibc the wheel runs on: zig links against this version's symbols.
MANYLINUX := manylinux_2_17

.PHONY: all demo docs test test-long test-wheel wheel fuzz lint fmt bench bench-peers bench-stiff accuracy setup system-deps clean

all: test

## Set-up ---------------------------------------------------------------------------------

system-deps:
	@scripts/system-deps.sh

$(VENV)/.ready: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q 'maturin>=1.9,<2' 'ziglang>=0.13' 'auditwheel>=6'
	touch $@

# How maturin builds the extension module, for the wheel and for the development install alike:
# stripped, and linked by zig (from the ziglang package, which maturin finds through the venv's
# python) against the symbols of glibc MANYLINUX names. The same flags make the same cargo
# build, so whichever of the two runs second finds it done instead of compiling the crate a
# second time (a release build with LTO, about 4 minutes on two cores). A profile of the
# installed module has no symbols: build one with `cargo build --release --lib --features python`.
ZIG_BUILD := --strip --zig --compatibility $(MANYLINUX)
# The venv's bin first on PATH: maturin finds zig through the venv's python.
VENV_PATH := PATH="$(CURDIR)/$(VENV)/bin:$$PATH"

# The extension module, built in release mode (pyproject.toml's [tool.maturin] profile) into the
# package (an editable install: python/ is the package, the module copied into it), with the
# package's dependencies, the `dev` dependency group (tests, linters, docs: pyproject.toml) and
# the `ray` extra, so the sweep's Ray tests run in CI.
$(VENV)/.built: $(VENV)/.ready $(RUST_SOURCES) pyproject.toml
	$(VENV_PATH) MATURIN_PEP517_ARGS="$(ZIG_BUILD)" \
		$(PY) -m pip install -q --no-build-isolation -e '.[ray]' --group dev
	touch $@

setup: system-deps $(VENV)/.built

## Main jobs -------------------------------------------------------------------------------

demo: setup
	$(PY) -m rustcloth demo

# The Rust tests optimised (Cargo.toml's `fast-tests` profile says why); the Python suite in
# two processes (pytest-xdist): much of it waits on subprocesses, Ray and Xvfb, or runs Python
# on one core, so two workers overlap that (the testing notebook, docs/notes/testing.md).
test: setup lint
	cargo test -q --profile fast-tests
	$(PY) -m pytest -q -m "not long" -n 2 --dist loadgroup
	$(MAKE) --no-print-directory test-wheel

# The documentation site: docs/*.md and the API reference from the docstrings (mkdocs.yml), in
# site/. --strict fails on a broken link or cross-reference and a page missing from the
# navigation; not -q, which hides the warnings --strict counts. `make test` builds it too
# (tests/test_docs.py), and runs every docstring example and every example in examples/.
docs: setup
	$(PY) -m mkdocs build --strict -d site

# The distributions: one stripped abi3 wheel that runs on glibc 2.17 and later (ZIG_BUILD), and
# an sdist.
wheel: dist/.built

dist/.built: $(VENV)/.ready $(WHEEL_INPUTS)
	rm -rf dist
	$(VENV_PATH) $(VENV)/bin/maturin build -q --release $(ZIG_BUILD) -o dist
	$(VENV)/bin/maturin sdist -o dist
	$(VENV)/bin/auditwheel show dist/*.whl
	touch $@

# The wheel as a user gets it: installed into fresh venvs outside the repository, the test suite
# run from a copy there (scripts/test-wheel.sh).
test-wheel: wheel
	scripts/test-wheel.sh dist/*.whl

test-long: setup
	$(PY) -m pytest -q

# The property-based fuzz suite (tests/fuzz.rs, the `fuzz` module of the `integration` test
# binary) at length: `make test` runs it briefly with a fixed seed; this runs FUZZ_CASES cases
# of each property in release mode with a fresh seed (printed; FUZZ_SEED=... repeats a run). A
# failure prints the shrunk input.
FUZZ_CASES ?= 20000
ifndef FUZZ_SEED
FUZZ_SEED := $(shell od -An -N4 -tu4 /dev/urandom | tr -d ' ')
endif

fuzz:
	@echo "fuzz: $(FUZZ_CASES) cases per property, seed $(FUZZ_SEED)"
	PROPTEST_CASES=$(FUZZ_CASES) PROPTEST_RNG_SEED=$(FUZZ_SEED) cargo test --release --test integration fuzz::

# The module-cycle check: no Rust subsystem and no Python module imports one that imports it
# back (scripts/module_cycles.py says what counts).
lint: setup
	cargo fmt --check
	cargo clippy -q --all-targets --all-features -- -D warnings
	$(VENV)/bin/ruff check python tests benches examples scripts/docs_roles.py
	$(VENV)/bin/python -m mypy --strict python/rustcloth
	$(VENV)/bin/python -m mypy --strict tests/typecheck
	$(VENV)/bin/python -m mypy.stubtest rustcloth --allowlist scripts/stubtest-allowlist.txt
	python3 scripts/module_cycles.py

fmt:
	cargo fmt
	$(VENV)/bin/ruff check --fix python tests benches

bench: setup
	cargo bench --bench step
	$(PY) benches/bench_numpy.py

# The accuracy-versus-time study: regenerates docs/accuracy.md and docs/accuracy.png.
accuracy: setup
	$(PY) -m rustcloth accuracy --out docs

bench-peers: setup
	benches/peers/setup.sh
	.venv-peers/bin/python benches/peers/run.py

# Stiff cloth at 1/60 s (issue 14): rustcloth's solvers and newton's VBD on one scene; writes
# docs/stiff.md and docs/stiff.png (about 40 minutes; BEFORE=python adds the old code's rows).
bench-stiff: setup
	benches/peers/setup.sh
	$(PY) benches/peers/stiff.py $(if $(BEFORE),--before $(BEFORE))

clean:
	rm -rf target dist site $(VENV) python/rustcloth/*.so
