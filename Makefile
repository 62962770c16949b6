# make demo: set up and run the demo; make test: set up and run every check (what CI runs).
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
VENV ?= .venv
PY := $(VENV)/bin/python
PYABS = $(abspath $(PY))
PYTHON ?= python3

.PHONY: docs-examples c-deps c-header c-header-check c-lib c-install c-test c-bench crate-copy-check demo test venv dist aarch64 wheel install-test crates docs lint rust-test py-test typecheck bench bench-py bench-search bench-search-py readme-speed readme-results thresholds bench-pcd fuzz fuzz-smoke fuzz-deps cargo-fuzz-run bench-reg bench-basin bench-step audit clean stubs

$(VENV)/.ready: requirements-dev.txt pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements-dev.txt
	touch $@

venv: $(VENV)/.ready

## The release artefacts in dist/: an sdist and one abi3 wheel (CPython >= 3.9) tagged
## manylinux2014 (glibc >= 2.17: Ubuntu 18.04+, ROS Noetic, Jetson L4T), linked by zig (from the
## ziglang package) against glibc 2.17 symbols; tools/check_wheel.py checks its tags and, with
## auditwheel, what the binary really needs. Everything below tests this one wheel.
dist: venv
	rm -rf dist
	$(VENV)/bin/maturin sdist --out dist
	PATH="$(abspath $(VENV))/bin:$$PATH" $(VENV)/bin/maturin build --release --zig \
		--compatibility manylinux2014 --out dist --interpreter $(PY)
	$(PY) tools/check_wheel.py dist/*.whl

## Optional, not part of make test: the aarch64 wheel (manylinux2014, cross-linked by zig),
## checked like the x86-64 one, and the core and simulator test suites run under qemu. Needs the
## aarch64 standard library (rustup target add, which downloads it) and Debian's qemu-user,
## gcc-aarch64-linux-gnu (the test binaries' linker) and libc6-dev-arm64-cross. See docs/arm.md.
AARCH64 := aarch64-unknown-linux-gnu
aarch64: venv
	rustup target add $(AARCH64)
	rm -rf dist/aarch64
	PATH="$(abspath $(VENV))/bin:$$PATH" $(VENV)/bin/maturin build --release --zig \
		--target $(AARCH64) --compatibility manylinux2014 --out dist/aarch64
	$(PY) tools/check_wheel.py dist/aarch64/*.whl aarch64
	CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc \
	CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu" \
		cargo test -p solid-lidar -p solid-lidar-sim --target $(AARCH64)

## Install the dist wheel into the development virtualenv (pytest, mypy, stubtest, demo use it).
wheel: dist
	$(PY) -m pip install --quiet --force-reinstall --no-deps dist/*.whl

## As a user would: the wheel, then the sdist (which compiles), each installed by file into a
## fresh virtualenv, each running the README's Python examples and the solid command. The sdist
## check is whether it builds and works, not how fast the result runs: it compiles without LTO
## and in its own target folder, so that later runs reuse the dependencies.
install-test: dist
	rm -rf build/venv-wheel build/venv-sdist
	$(PYTHON) -m venv build/venv-wheel
	build/venv-wheel/bin/python -m pip install --quiet dist/*.whl
	cd build && venv-wheel/bin/python ../tools/readme_examples.py --run ../README.md
	cd build && venv-wheel/bin/python ../tools/readme_examples.py --run ../docs/describe.md
	cd build && venv-wheel/bin/python ../tools/readme_examples.py --run ../docs/loops.md
	build/venv-wheel/bin/solid presets
	$(PYTHON) -m venv build/venv-sdist
	@# The sdist's files carry the archive's old mtimes: cargo would take this project's crates
	@# from an earlier run as fresh. Only the dependencies are reused.
	cargo clean --quiet --release --target-dir "$(CURDIR)/target/sdist" -p solid-lidar -p solid-lidar-sim -p solid-lidar-py
	CARGO_TARGET_DIR="$(CURDIR)/target/sdist" CARGO_PROFILE_RELEASE_LTO=off CARGO_PROFILE_RELEASE_CODEGEN_UNITS=16 \
		build/venv-sdist/bin/python -m pip install --quiet dist/*.tar.gz
	cd build && venv-sdist/bin/python ../tools/readme_examples.py --run ../README.md
	build/venv-sdist/bin/solid presets >/dev/null

## The publishable crates package and would publish (--allow-dirty: this checks packaging, not
## whether the work tree is committed).
crates:
	cargo publish --dry-run --allow-dirty -p solid-lidar -p solid-lidar-sim

## The documentation: the site (warnings are errors) and the crates' rustdoc (docs.rs).
docs: venv
	$(VENV)/bin/mkdocs build --strict --site-dir build/site
	RUSTDOCFLAGS="-D warnings" cargo doc --no-deps -p solid-lidar -p solid-lidar-sim

## The core copied out of this repository into another project and depended on by path (what
## docs/rust.md tells users): it must carry no symlink and inherit nothing from this workspace.
## Builds a tiny consumer of the copy offline (the dependencies are in ~/.cargo already), into
## this workspace's target folder: the copy's dependencies are then those `make crates` built
## (the same versions, features and profile), only the copy itself compiles.
crate-copy-check:
	@links=$$(find crates/solid-core -type l); [ -z "$$links" ] || { echo "symlinks in crates/solid-core (dangle in a copy): $$links"; exit 1; }
	cmp LICENSE-MIT crates/solid-core/LICENSE-MIT && cmp LICENSE-APACHE crates/solid-core/LICENSE-APACHE
	tmp=$$(mktemp -d) && trap 'rm -rf "$$tmp"' EXIT && \
	cp -r crates/solid-core "$$tmp/solid-lidar" && mkdir -p "$$tmp/consumer/src" && \
	printf '[package]\nname = "consumer"\nversion = "0.0.0"\nedition = "2021"\n\n[dependencies]\nsolid-lidar = { path = "../solid-lidar" }\n\n[workspace]\n' > "$$tmp/consumer/Cargo.toml" && \
	printf 'fn main() {\n    let cfg = solid_lidar::Config::preset("hdl64").unwrap();\n    let xyz = [10.0f32, 0.0, -1.0, 0.0, 12.0, 0.5];\n    let d = solid_lidar::Describer::new(cfg).unwrap().describe(solid_lidar::Points::new(&xyz, 3).unwrap()).unwrap();\n    assert_eq!(d.stats.n_kept, 2);\n}\n' > "$$tmp/consumer/src/main.rs" && \
	cp Cargo.lock "$$tmp/consumer/" && \
	(cd "$$tmp/consumer" && CARGO_TARGET_DIR="$(CURDIR)/target" cargo run --quiet --offline)
	@echo "crates/solid-core builds by path from a copy"

## The C API (crates/solid-c; docs/c.md): libsolid.so and libsolid.a, include/solid.h generated by
## cbindgen, the CMake package (find_package(solid): solid::solid, solid::solid_static) and
## solid.pc. `make c-install PREFIX=DIR` installs them into DIR. cmake, cbindgen, pkg-config and
## valgrind come from Debian's packages, installed when missing (as root, as CI runs); cbindgen
## from cargo when Debian has none. The header check compares with the committed header, so use
## the cbindgen that generated it (Debian bookworm's 0.24.3).
C_VERSION := $(shell sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -1)
C_LIBDIR = $(or $(CARGO_TARGET_DIR),target)/release
C_BUILD := build/c
PREFIX ?= $(CURDIR)/$(C_BUILD)/prefix
APT_GET := DEBIAN_FRONTEND=noninteractive apt-get

c-deps:
	@missing=""; for t in cmake:cmake pkg-config:pkg-config valgrind:valgrind g++:g++ cbindgen:cbindgen; do \
	  command -v $${t%%:*} >/dev/null || missing="$$missing $${t##*:}"; done; \
	if [ -n "$$missing" ]; then $(APT_GET) update -qq && $(APT_GET) install -y -qq $$missing; fi
	@command -v cbindgen >/dev/null || cargo install --locked cbindgen

c-header: c-deps
	cbindgen --quiet --config crates/solid-c/cbindgen.toml --output crates/solid-c/include/solid.h crates/solid-c

c-header-check: c-deps
	mkdir -p $(C_BUILD)
	cbindgen --quiet --config crates/solid-c/cbindgen.toml --output $(C_BUILD)/solid.h crates/solid-c
	diff -u crates/solid-c/include/solid.h $(C_BUILD)/solid.h || { echo "crates/solid-c/include/solid.h is stale: run make c-header"; exit 1; }

c-lib:
	cargo build --release -p solid-c

c-install: c-deps c-lib
	install -d "$(PREFIX)/include" "$(PREFIX)/lib/cmake/solid" "$(PREFIX)/lib/pkgconfig"
	install -m 644 crates/solid-c/include/solid.h "$(PREFIX)/include/"
	install -m 755 $(C_LIBDIR)/libsolid.so "$(PREFIX)/lib/"
	install -m 644 $(C_LIBDIR)/libsolid.a "$(PREFIX)/lib/"
	sed 's/@VERSION@/$(C_VERSION)/' crates/solid-c/cmake/solidConfig.cmake.in > "$(PREFIX)/lib/cmake/solid/solidConfig.cmake"
	sed 's/@VERSION@/$(C_VERSION)/' crates/solid-c/cmake/solidConfigVersion.cmake.in > "$(PREFIX)/lib/cmake/solid/solidConfigVersion.cmake"
	sed 's/@VERSION@/$(C_VERSION)/' crates/solid-c/cmake/solid.pc.in > "$(PREFIX)/lib/pkgconfig/solid.pc"
	@echo "installed solid $(C_VERSION) into $(PREFIX)"

## The examples built against the installed package as a user builds them (examples/CMakeLists.txt:
## find_package, pkg-config, the static library, AddressSanitizer), then tests/c/c_api_check.py runs
## them against the Python package and under valgrind (in parallel, pytest-xdist).
C_CMAKE = cmake -S examples -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_PREFIX_PATH="$(PREFIX)" --log-level=WARNING
c-test: wheel c-header-check
	$(MAKE) --no-print-directory c-install PREFIX="$(CURDIR)/$(C_BUILD)/prefix"
	rm -rf $(C_BUILD)/cmake $(C_BUILD)/pkgconfig $(C_BUILD)/static $(C_BUILD)/asan
	$(C_CMAKE) -B $(C_BUILD)/cmake && cmake --build $(C_BUILD)/cmake -j 2
	PKG_CONFIG_PATH="$(CURDIR)/$(C_BUILD)/prefix/lib/pkgconfig" $(C_CMAKE) -B $(C_BUILD)/pkgconfig -DSOLID_PKGCONFIG=ON && cmake --build $(C_BUILD)/pkgconfig -j 2
	$(C_CMAKE) -B $(C_BUILD)/static -DSOLID_STATIC=ON && cmake --build $(C_BUILD)/static -j 2
	$(C_CMAKE) -B $(C_BUILD)/asan -DSOLID_SANITIZE=ON && cmake --build $(C_BUILD)/asan -j 2
	SOLID_C_BUILD="$(CURDIR)/$(C_BUILD)" PATH="$(abspath $(VENV))/bin:$$PATH" $(PY) -m pytest -n auto tests/c/c_api_check.py


## The C API's describe against the Rust call in one process, and the bytes a warm C call
## allocates (docs/c.md quotes the figures).
c-bench:
	cargo bench -p solid-lidar-benches --bench c_api

demo: wheel
	$(VENV)/bin/solid demo

lint:
	cargo fmt --all -- --check
	cargo clippy --workspace --all-targets --all-features -- -D warnings
	# The core alone, its default features (the workspace's build turns on `unstable-internals`).
	cargo clippy -p solid-lidar --all-targets -- -D warnings

rust-test:
	cargo test --workspace
	cargo build -p solid-lidar --no-default-features
	cargo build -p solid-lidar --no-default-features --features alloc
	# The unit tests without threads or std (the serial paths of the database, among others).
	cargo test -p solid-lidar --no-default-features --features alloc --lib

## The Python tests in two steps: most of them spread over the cores (pytest-xdist, `--dist
## loadfile`: a file's tests in one process, so that a module's fixtures are made once), then the
## tests marked serial (tests/conftest.py: the ROS 2 node against a player over the middleware,
## Ctrl-C within a bound) alone, as their timing needs.
py-test: wheel
	$(PY) -m pytest -n auto --dist loadfile -m "not serial" --durations=25
	$(PY) -m pytest -m serial --durations=10

## Write python/solid/_solid.pyi from its hand-written parts (stubs/*.pyi, one per binding module)
## and the core's parameter tables, and the parameter tables of docs/spec.md (tools/stubgen.py);
## `make test` fails when either is stale.
stubs: wheel
	$(PY) tools/stubgen.py

typecheck: wheel
	$(PY) tools/stubgen.py --check
	mkdir -p build
	$(PY) tools/readme_examples.py README.md build/readme_blocks.py
	$(PY) tools/readme_examples.py docs/describe.md build/docs_describe_blocks.py
	$(PY) tools/readme_examples.py docs/loops.md build/docs_loops_blocks.py
	$(PY) tools/readme_examples.py docs/slam.md build/docs_slam_blocks.py
	$(PY) tools/readme_examples.py docs/view.md build/docs_view_blocks.py
	$(VENV)/bin/mypy --strict python/solid tests tools build/readme_blocks.py build/docs_describe_blocks.py build/docs_loops_blocks.py build/docs_slam_blocks.py build/docs_view_blocks.py
	$(VENV)/bin/mypy --strict fuzz/python
	$(PY) -m mypy.stubtest solid._solid

## Every fenced command and Python block of the README and the docs, run as written in a
## workspace where their placeholder names (hku1-avia, my_run, run1, odom.txt, scan.pcd...) are the
## shared data (tools/readme_examples.py; a block that cannot run here carries a docs-check marker
## with its reason, printed). The README's, describe's and loops' Python blocks run in install-test.
## Each page runs in a fresh workspace of its own, so pages run two at a time, the two longest
## first (docs/slam.md, ~40 s of CPU, and docs/loops.md's commands, ~50 s; the rest, ~30 s, follow
## beside slam.md), so that neither waits alone at the end.
DOC_PAGES := $(wildcard docs/*.md)
DOC_RUNS := docs/slam.md --shell-only:docs/loops.md \
	$(filter-out docs/slam.md docs/describe.md docs/loops.md,$(DOC_PAGES)) \
	--shell-only:README.md --shell-only:docs/describe.md
docs-examples: wheel
	printf '%s\n' $(DOC_RUNS) | tr ':' ' ' | xargs -P 2 -L 1 $(PY) tools/readme_examples.py --run-docs

test: lint rust-test crates crate-copy-check docs py-test c-test typecheck fuzz-smoke install-test docs-examples

bench:
	cargo bench -p solid-lidar-benches

## BENCH_JSON=path also writes the figures as JSON (for the README's speed table).
bench-py: wheel
	$(PY) benches/python_baseline.py $(if $(BENCH_JSON),--json $(BENCH_JSON))

## Search against brute force, the kd-tree and the sketch on realistic databases (10k-1M entries).
bench-search:
	cargo bench -p solid-lidar-benches --bench search

## Search, batch search and bulk add against faiss-cpu and numpy (faiss is installed for this only).
bench-search-py: wheel
	$(PY) -m pip install --quiet -r benches/requirements-bench.txt
	$(PY) benches/search_peers.py

## Rewrite the README's speed tables: both Python benchmarks write what they print to
## benches/results/*.json, and tools/readme_speed.py turns that into the README block (run it on a
## quiet machine: every figure is a ratio to a peer timed in the same run, but a busy core still
## skews them). STEP_BASELINE=DIR (an older build, pip install --target DIR <wheel>) and
## STEP_BASELINE_LABEL="main @ <commit>" put the verified step beside it.
readme-speed: wheel
	$(PY) -m pip install --quiet -r benches/requirements-bench.txt
	mkdir -p benches/results
	$(PY) benches/python_baseline.py --json benches/results/describe.json
	$(PY) benches/search_peers.py --json benches/results/search.json
	SOLID_BENCH_MAP_SIZES=1000,10000,100000,1000000 SOLID_BENCH_JSON=$(CURDIR)/benches/results/maps.json \
		cargo bench -p solid-lidar-benches --bench maps
	$(PY) benches/detector_step.py --json benches/results/step.json \
		$(if $(STEP_BASELINE),--baseline $(STEP_BASELINE) --baseline-label "$(STEP_BASELINE_LABEL)")
	$(PY) tools/readme_speed.py

## Rewrite the README's hku1 results (SOLiD and Scan Context, 3 m and 5 m) from fresh `solid eval` runs.
readme-results: wheel
	$(PY) tools/readme_results.py

## Measure the loop threshold of every preset (the defaults in crates/solid-core/src/config.rs).
thresholds: wheel
	$(PY) tools/thresholds.py

## Reading a KITTI-sized PCD, binary vs binary_compressed (issue 10: within 2x).
bench-pcd: wheel
	$(PY) benches/pcd_read.py

## Fuzzing. Atheris harnesses for the Python readers (fuzz/python, one per area) and cargo-fuzz
## targets (fuzz/, nightly toolchain, AddressSanitizer) for every parser and decoder of the core:
## the LZF decoder (lzf), the database file (db_from_bytes: what it accepts re-encodes, reads back
## the same and searches alike by brute force and kd-tree), the place and cloud wire forms
## (place_decode, reg_decode_cloud), plus describe on arbitrary points and configs (describe: the
## AVX2 and portable copies and float32 and float64 points give the same bits), the docs/spec.md §5
## scorer (score) and registration on arbitrary clouds, poses and yaws (register). Corpora are seeded at
## run time from ../shared/data into build/fuzz/corpus (fuzz/python/seed_lzf.py, seed_core.py).
## `make fuzz` runs each for FUZZ_SECONDS; `make test` runs FUZZ_SMOKE_SECONDS of each. Both first
## install what is missing (fuzz-deps: the nightly toolchain, cargo-fuzz into ~/.cargo/bin, the fuzz
## crate's dependencies), then build offline. Each run prints how many inputs it executed and fails
## when that is none. A contract violation stops the run and keeps the input in build/fuzz/artifacts.
FUZZ_SECONDS ?= 60
FUZZ_SMOKE_SECONDS ?= 2
FUZZ_AREAS := pcd ply npy npz bin poses rosbag1 mcap
CARGO_FUZZ_TARGETS := lzf db_from_bytes place_decode reg_decode_cloud describe score register
NIGHTLY_FUZZ := cargo +nightly fuzz

# Installed once under ~/.cargo (a stable path a CI cache can keep), then only checked.
fuzz-deps:
	cargo +nightly --version >/dev/null 2>&1 || rustup toolchain install nightly --profile minimal
	$(NIGHTLY_FUZZ) --version >/dev/null 2>&1 || cargo install --locked cargo-fuzz
	cd fuzz && cargo +nightly fetch --quiet

# The inputs one libFuzzer run ($$name, log $(1)) executed, from its final stats; none is a failure.
fuzz_executed = n=$$(sed -n 's/^stat::number_of_executed_units: *//p' $(1) | tail -1); \
  echo "$$name: $${n:-0} inputs executed"; [ "$${n:-0}" -gt 0 ] || { echo "$$name executed no input"; exit 1; }

# Each run is one process on one core: two at a time (a sub-make with -j 2), each target's log
# in build/fuzz/TARGET.log and its tail printed when it fails.
define run_fuzz
	mkdir -p build/fuzz
	$(MAKE) --no-print-directory -j 2 FUZZ_TIME=$(1) $(addprefix atheris-,$(FUZZ_AREAS))
endef

define run_cargo_fuzz
	mkdir -p build/fuzz/artifacts
	(cd fuzz/python && $(PYABS) seed_lzf.py ../../build/fuzz/corpus/lzf)
	$(PY) fuzz/python/seed_core.py build/fuzz/corpus
	cd fuzz && CARGO_NET_OFFLINE=true $(NIGHTLY_FUZZ) build
	$(MAKE) --no-print-directory -j 2 FUZZ_TIME=$(1) $(addprefix cargo-fuzz-,$(CARGO_FUZZ_TARGETS))
endef

# One harness for FUZZ_TIME seconds (run_fuzz and run_cargo_fuzz start them).
.PHONY: $(addprefix atheris-,$(FUZZ_AREAS)) $(addprefix cargo-fuzz-,$(CARGO_FUZZ_TARGETS))
$(addprefix atheris-,$(FUZZ_AREAS)): atheris-%:
	@echo "atheris $*: $(FUZZ_TIME) s"
	@(cd fuzz/python && $(PYABS) fuzz.py $* -max_total_time=$(FUZZ_TIME) -timeout=10 -rss_limit_mb=4096 -print_final_stats=1) \
	  > build/fuzz/$*.log 2>&1 || { tail -40 build/fuzz/$*.log; exit 1; }
	@name="atheris $*"; $(call fuzz_executed,build/fuzz/$*.log)

$(addprefix cargo-fuzz-,$(CARGO_FUZZ_TARGETS)): cargo-fuzz-%:
	@echo "cargo-fuzz $*: $(FUZZ_TIME) s"
	@(cd fuzz && CARGO_NET_OFFLINE=true $(NIGHTLY_FUZZ) run $* ../build/fuzz/corpus/$* -- -max_total_time=$(FUZZ_TIME) \
	  -rss_limit_mb=4096 -artifact_prefix=../build/fuzz/artifacts/$*- -print_final_stats=1) \
	  > build/fuzz/$*.log 2>&1 || { tail -40 build/fuzz/$*.log; exit 1; }
	@name="cargo-fuzz $*"; $(call fuzz_executed,build/fuzz/$*.log)

fuzz: wheel fuzz-deps
	$(call run_fuzz,$(FUZZ_SECONDS))
	$(call run_cargo_fuzz,$(FUZZ_SECONDS))

## The cargo-fuzz targets alone (after `make wheel`, which the seeders import).
cargo-fuzz-run:
	$(call run_cargo_fuzz,$(FUZZ_SECONDS))

fuzz-smoke: wheel fuzz-deps
	$(call run_fuzz,$(FUZZ_SMOKE_SECONDS))
	$(call run_cargo_fuzz,$(FUZZ_SMOKE_SECONDS))

## Registration speed: solid against small-gicp on the same hku1 pairs, single-threaded.
bench-reg: wheel
	$(PY) benches/registration.py

## The convergence basin: true revisit pairs of hku1-avia and a simulated OS1-64 drive registered from
## starts 1-3 m / ±30° off the truth and from the identity, solid beside small-gicp (a few minutes).
bench-basin: wheel
	$(PY) benches/reg_basin.py

## The verified detector step: CPU per step of the shipped detector on hku1-avia (with and without
## poses) and a simulated 360° OS1-64 drive, beside small-gicp on the same pairs (a few minutes).
## Beside an older build: $(PY) benches/detector_step.py --baseline DIR (pip install --target DIR <wheel>).
bench-step: wheel
	$(PY) benches/detector_step.py

## The hardening audit of issue 10 (allocation limits, hostile files, API edges; a few minutes):
## prints area | cases tried | handled cleanly | wrong.
audit: wheel
	$(PY) tools/hardening_audit.py

clean:
	rm -rf dist build $(VENV) target fuzz/target
