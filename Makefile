# make demo: set up and run the demo; make test: set up and run every check (what CI runs).
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
VENV ?= .venv
PY := $(VENV)/bin/python
PYABS = $(abspath $(PY))
PYTHON ?= python3

.PHONY: demo test venv wheel lint rust-test py-test typecheck bench bench-py readme-results thresholds bench-pcd fuzz fuzz-smoke fuzz-deps clean

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
	$(VENV)/bin/mypy --strict fuzz/python
	$(PY) -m mypy.stubtest solid._solid

test: lint rust-test py-test typecheck fuzz-smoke

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

## Reading a KITTI-sized PCD, binary vs binary_compressed (issue 10: within 2x).
bench-pcd: wheel
	$(PY) benches/pcd_read.py

## Fuzzing. Atheris harnesses for the Python readers (fuzz/python, one per area) and a cargo-fuzz
## target for the LZF decoder (fuzz/, nightly toolchain); corpora are seeded at run time from
## ../shared/data into build/fuzz. `make fuzz` runs each for FUZZ_SECONDS; `make test` runs
## FUZZ_SMOKE_SECONDS of each. A contract violation stops the run and keeps the input in
## build/fuzz/artifacts.
FUZZ_SECONDS ?= 60
FUZZ_SMOKE_SECONDS ?= 2
FUZZ_AREAS := pcd ply npy npz bin poses rosbag1 mcap
NIGHTLY_FUZZ := cargo +nightly fuzz

fuzz-deps:
	cargo +nightly --version >/dev/null 2>&1 || { echo "cargo-fuzz needs the nightly toolchain (rustup toolchain install nightly)"; exit 1; }
	$(NIGHTLY_FUZZ) --version >/dev/null 2>&1 || cargo install --locked cargo-fuzz

define run_fuzz
	mkdir -p build/fuzz
	for a in $(FUZZ_AREAS); do \
	  echo "atheris $$a: $(1) s"; \
	  (cd fuzz/python && $(PYABS) fuzz.py $$a -max_total_time=$(1) -timeout=10 -rss_limit_mb=4096 -print_final_stats=1) \
	    > build/fuzz/$$a.log 2>&1 || { tail -40 build/fuzz/$$a.log; exit 1; }; \
	  grep -h "stat::number_of_executed_units" build/fuzz/$$a.log || true; \
	done
endef

fuzz: wheel fuzz-deps
	$(call run_fuzz,$(FUZZ_SECONDS))
	(cd fuzz/python && $(PYABS) seed_lzf.py ../../build/fuzz/corpus/lzf)
	cd fuzz && $(NIGHTLY_FUZZ) run lzf ../build/fuzz/corpus/lzf -- -max_total_time=$(FUZZ_SECONDS) -artifact_prefix=../build/fuzz/artifacts/

fuzz-smoke: wheel
	$(call run_fuzz,$(FUZZ_SMOKE_SECONDS))
	@if $(NIGHTLY_FUZZ) --version >/dev/null 2>&1; then \
	  (cd fuzz/python && $(PYABS) seed_lzf.py ../../build/fuzz/corpus/lzf) && \
	  cd fuzz && $(NIGHTLY_FUZZ) run lzf ../build/fuzz/corpus/lzf -- -max_total_time=$(FUZZ_SMOKE_SECONDS) -artifact_prefix=../build/fuzz/artifacts/; \
	else \
	  echo "cargo-fuzz smoke skipped: needs the nightly toolchain and cargo-fuzz (make fuzz-deps);"; \
	  echo "crates/solid-core/tests/lzf.rs checks the same oracle on stable"; \
	fi

clean:
	rm -rf dist build $(VENV) target
