# The two commands a newcomer runs: `make demo` and `make test`. Both install the Debian 12
# dependencies (idempotent) and build first.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
DEMO_OUT ?= demo-output

.PHONY: all deps configure build demo test test-unit soak bench clean

all: build

deps:
	bash deploy/install-deps.sh

configure: deps
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

# The main job: a scripted sculpting session on the default scene, results in $(DEMO_OUT)/.
demo: build
	$(BUILD_DIR)/bin/sculpt demo --out $(DEMO_OUT)

# Every test except the hand-run soaks, through ctest.
test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS) -LE soak --timeout 1500

soak: build
	cd $(BUILD_DIR) && ctest --output-on-failure -L soak

bench: build
	$(BUILD_DIR)/bin/sculpt-bench edit --json
	$(BUILD_DIR)/bin/sculpt-bench accuracy --json

clean:
	rm -rf $(BUILD_DIR)
