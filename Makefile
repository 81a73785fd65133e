# The two commands a newcomer runs: `make demo` and `make test`. Both install the Debian 12
# dependencies (idempotent) and build first.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
DEMO_OUT ?= demo-output

.PHONY: all deps configure build demo demo-local test test-asan soak fuzz bench bench-server bench-replication clean

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

# The unit, stability and integration tests under AddressSanitizer + UndefinedBehaviorSanitizer
# (gcc) in their own build directory; -O1 keeps the sanitized tests fast enough for CI. Not run:
# browser tests, soaks, benchmarks (not built there), and EditStability's 10,000-stroke run (its
# 4 minutes in Release would be most of the budget; the other stability tests cover the same
# code), and AcceptBackoffTest's EMFILE run (out of descriptors, the sanitizer runtime's own
# memory probe fails and UBSan's vptr check reports Boost.System's valid error category as an
# invalid object). See docs/sanitizers.md. The compile cache ignores the build directory's path
# (CCACHE_NOHASHDIR) so a fresh clone reuses the sanitized objects of an earlier one.
ASAN_BUILD_DIR ?= build-asan
SANITIZER_ENV = ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=0 \
	LSAN_OPTIONS=suppressions=$(CURDIR)/tests/sanitizers/lsan.supp:print_suppressions=0 \
	UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:suppressions=$(CURDIR)/tests/sanitizers/ubsan.supp
test-asan: deps
	cmake -S . -B $(ASAN_BUILD_DIR) -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DSCULPT_SANITIZE=address,undefined
	CCACHE_NOHASHDIR=true $(SANITIZER_ENV) cmake --build $(ASAN_BUILD_DIR) -j $(JOBS)
	cd $(ASAN_BUILD_DIR) && $(SANITIZER_ENV) ctest --output-on-failure -j $(JOBS) \
	  -L 'unit|stability|integration' -LE 'soak|browser' --timeout 1500 \
	  -E '^(EditStability.TenThousandPressStrokesKeepVolume|AcceptBackoffTest.AcceptLoopPausesOnEmfileLogsOnceAndRecovers)$$'

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
