# make demo: set up and run the demo; make test: set up and run every check (what CI runs).
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
VENV ?= .venv
PY := $(VENV)/bin/python
PYTHON ?= python3

.PHONY: demo test venv wheel lint rust-test py-test typecheck bench bench-py readme-results thresholds clean

$(VENV)/.ready: requirements-dev.txt pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements-dev.txt
	touch $@

venv: $(VENV)/.ready

## Build the release wheel with maturin and install it into the virtualenv.
wheel: venv
	rm -rf dist
	$(VENV)/bin/maturin build --release --out dist --interpreter $(PY)
	$(PY) -m pip install --quiet --force-reinstall --no-deps dist/*.whl

demo: wheel
	$(VENV)/bin/solid demo

lint:
	cargo fmt --all -- --check
	cargo clippy --workspace --all-targets --all-features -- -D warnings

rust-test:
	cargo test --workspace
	cargo build -p solid-lidar --no-default-features
	cargo build -p solid-lidar --no-default-features --features alloc

py-test: wheel
	$(PY) -m pytest

typecheck: wheel
	mkdir -p build
	$(PY) tools/readme_examples.py README.md build/readme_blocks.py
	$(VENV)/bin/mypy --strict python/solid tests build/readme_blocks.py
	$(PY) -m mypy.stubtest solid._solid

test: lint rust-test py-test typecheck

bench:
	cargo bench -p solid-lidar-benches

bench-py: wheel
	$(PY) benches/python_baseline.py

## Rewrite the README's hku1 results (SOLiD and Scan Context, 3 m and 5 m) from fresh `solid eval` runs.
readme-results: wheel
	$(PY) tools/readme_results.py

## Measure the loop threshold of every preset (the defaults in crates/solid-core/src/config.rs).
thresholds: wheel
	$(PY) tools/thresholds.py

clean:
	rm -rf dist build $(VENV) target
