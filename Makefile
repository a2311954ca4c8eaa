# Quick start (a fresh Debian 12 machine):
#   make demo   installs what is missing, builds, simulates a town drive and runs SLAM on it
#   make test   installs what is missing, builds and runs the whole test suite
#   make bench-quick / make bench   the benchmark report, bench/results/REPORT.md with plots
#               (under 10 minutes / about 75 minutes)
#   make bench-repro   makes the quick report twice: every accuracy figure must repeat
BUILD ?= build
JOBS ?= $(shell nproc)
DEMO_SCENARIO ?= rawlogs/town-loop.yaml
DEMO_RAWLOG ?= $(BUILD)/rawlogs/town-loop.rawlog
DEMO_OUT ?= out/demo
DEMO_CONFIG ?= slam

.PHONY: all deps configure build demo test bench bench-quick bench-repro clean

all: build

deps:
	@bash scripts/install-deps.sh

configure: deps
	@cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null

build: configure
	@cmake --build $(BUILD) -j $(JOBS)

$(DEMO_RAWLOG): $(DEMO_SCENARIO) | build
	@mkdir -p $(dir $@)
	$(BUILD)/bin/rasterslam-sim --scenario $(DEMO_SCENARIO) -o $@

demo: build
	@$(MAKE) --no-print-directory $(DEMO_RAWLOG)
	$(BUILD)/bin/rasterslam run --rawlog $(DEMO_RAWLOG) --config $(DEMO_CONFIG) --out $(DEMO_OUT) --map-out $(DEMO_OUT)/map --overwrite
	$(BUILD)/bin/rasterslam-eval traj --gt $(DEMO_OUT)/groundtruth.tum --est $(DEMO_OUT)/trajectory.tum
	$(BUILD)/bin/rasterslam-eval loops --loops $(DEMO_OUT)/loops.txt --gt $(DEMO_OUT)/groundtruth.tum --plot $(DEMO_OUT)/loops-pr.png
	@echo "demo: outputs in $(DEMO_OUT)/ (trajectory.tum, trajectory.kitti, loops.txt, timings.csv, run.yaml, map/)"

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

bench: build
	BUILD=$(BUILD) bash scripts/bench-report.sh

bench-quick: build
	BUILD=$(BUILD) bash scripts/bench-report.sh --quick

bench-repro: build
	BUILD=$(BUILD) bash scripts/bench-repro.sh --quick

clean:
	rm -rf $(BUILD) out
