# A thin front door to CMake. `make demo` and `make test` set up what is missing, configure, build and run.
BUILD ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?=
DATA ?=

.PHONY: all setup configure build demo test bench fuzz clean

all: build

setup:
	@scripts/setup.sh $(SETUP_FLAGS)

configure: setup
	@cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release $(CMAKE_FLAGS) >/dev/null

build: configure
	@cmake --build $(BUILD) -j $(JOBS)

demo: configure
	@cmake --build $(BUILD) -j $(JOBS) --target feedid_cli
	@scripts/demo.sh $(BUILD)/feedid $(DATA)

test: SETUP_FLAGS = --extra
test: build
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

bench: SETUP_FLAGS = --extra
bench: build
	@for b in $(BUILD)/bench/bench_*; do [ -x "$$b" ] && "$$b"; done

# libFuzzer targets of the controller trace readers (clang; skipped with a message without it) for FUZZ_SECONDS each,
# and the reader tests under AddressSanitizer + UBSan.
fuzz: SETUP_FLAGS = --extra
fuzz: setup
	@FUZZ_SECONDS=$${FUZZ_SECONDS:-20} scripts/fuzz.sh

clean:
	@rm -rf $(BUILD)
