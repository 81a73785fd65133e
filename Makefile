# The two commands a newcomer runs: `make demo` and `make test`. Both install the Debian 12
# dependencies (idempotent) and build first.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
DEMO_OUT ?= demo-output

.PHONY: all deps configure build demo demo-local test soak fuzz bench bench-server bench-replication clean

all: build

deps:
	bash deploy/install-deps.sh

configure: deps
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

# The main job: sculptd on the default data directory (./sculpt-data) with simulated sculptors
# and a viewer for a bounded time; the result is exported to $(DEMO_OUT)/.
demo: build
	BIN=$(BUILD_DIR)/bin DEMO_OUT=$(DEMO_OUT) bash deploy/demo.sh

# The kernel alone, in-process: a scripted session on a sphere, results in $(DEMO_OUT)/local/.
demo-local: build
	$(BUILD_DIR)/bin/sculpt demo --out $(DEMO_OUT)/local

# Every test except the hand-run soaks, through ctest.
test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS) -LE soak --timeout 1500

soak: build
	cd $(BUILD_DIR) && ctest --output-on-failure -L soak

# libFuzzer targets (clang, build-fuzz/), FUZZ_SECONDS each; see docs/fuzzing.md.
FUZZ_SECONDS ?= 60
fuzz:
	tests/fuzz/run.sh $(FUZZ_SECONDS)

bench: build
	$(BUILD_DIR)/bin/sculpt-bench edit --json
	$(BUILD_DIR)/bin/sculpt-bench accuracy --json

# Server load runs (minutes): JSON per run in docs/server-bench/.
bench-server: build
	BIN=$(BUILD_DIR)/bin bash tests/bench/server_bench.sh docs/server-bench

# Replication runs (about a minute): replay vs leaf-delta replicas, mesh viewers, late join.
bench-replication: build
	BIN=$(BUILD_DIR)/bin bash tests/bench/replication_bench.sh docs/replication-bench

clean:
	rm -rf $(BUILD_DIR)
