#!/usr/bin/env bash
# Robustness of the trace readers (CSV, MATLAB .mat, SINUMERIK trace XML, TwinCAT Scope CSV, halscope/halsampler,
# MR Configurator2 and NI DAQ CSV) and of feedid watch's MQTT payload decoder (payload):
#   1. libFuzzer: each fuzz target (fuzz/) built with clang into build-fuzz/ and run for a bounded time,
#      seeded from the hand-made corpus in tests/fuzz/corpus/<reader>/, the kept regression inputs in
#      tests/fuzz/regressions/<reader>/ and the real files in ../shared/data (read only);
#   2. the reader tests (tests/io/test_readers.cpp) built with -DFEEDID_SANITIZE=ON (AddressSanitizer + UBSan) into
#      build-asan/ and run.
# Exits non-zero when a fuzzer finds a crash, a hang, a sanitizer report or unbounded memory, or when the sanitized
# tests fail. Without clang/libFuzzer the fuzzing part is skipped with a message (scripts/setup.sh --extra installs
# clang and libclang-rt-14-dev); the sanitizer part needs only the normal toolchain.
#
#   scripts/fuzz.sh              both parts, 30 s per fuzzer
#   scripts/fuzz.sh fuzz         only the fuzzers        scripts/fuzz.sh asan   only the sanitized tests
#   FUZZ_SECONDS=60 JOBS=2 scripts/fuzz.sh
#   FUZZ_READERS="mr_configurator ni_daq" scripts/fuzz.sh fuzz   only these fuzzers (payload: the MQTT decoder)
#   FUZZ_SEED=1 scripts/fuzz.sh  the same mutations on every run (CI): a fixed seed makes a short run a repeatable
#                                check, clean on every machine once it is clean here for longer; without it each run
#                                explores anew (what to run locally, for minutes)
#
# A crashing input is written to build-fuzz/artifacts/<reader>/; after fixing the reader, keep it as a regression
# test by copying it to tests/fuzz/regressions/<reader>/ (test_readers runs every file there).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
what=${1:-all}
seconds=${FUZZ_SECONDS:-30}
seed_option=()
[ -n "${FUZZ_SEED:-}" ] && seed_option=(-seed="$FUZZ_SEED")
jobs=${JOBS:-2}
shared=${FEEDID_SHARED_DATA:-$root/../shared/data}
readers=(${FUZZ_READERS:-csv mat sinumerik_trace twincat_scope halscope mr_configurator ni_daq payload})
status=0
# HDF5's own leaks on damaged v7.3 files are not feedid's (see the file); every other leak still fails.
export LSAN_OPTIONS="suppressions=$root/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
# An allocation the system cannot give returns null, as it does outside the sanitizer: HDF5 (behind libmatio's v7.3
# files) sizes some buffers from the file before it reads them, and on a damaged file asks for 171 GB
# (tests/fuzz/regressions/mat/v73_hdf5_asks_171GB.mat), fails to get it and refuses the file; without this ASan aborts
# there. Any allocation of over 1 GB that succeeds still fails the run (-malloc_limit_mb), as does any access error.
asan_options="allocator_may_return_null=1"

seeds_from_shared() {
  case "$1" in
    mat) echo "$shared/emps" ;;
    sinumerik_trace) echo "$shared/sinumerik-trace" ;;
    twincat_scope) echo "$shared/twincat-scope" ;;
    mr_configurator | ni_daq) echo "$shared/mitsubishi-mr" ;;
    *) ;;
  esac
}

run_fuzzers() {
  if ! command -v clang++ >/dev/null 2>&1; then
    echo "fuzz: skipped: clang++ not found (install the optional tools: scripts/setup.sh --extra)" >&2
    return 0
  fi
  local probe
  probe=$(mktemp -d)
  printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' >"$probe/p.cpp"
  if ! clang++ -fsanitize=fuzzer "$probe/p.cpp" -o "$probe/p" >/dev/null 2>&1; then
    rm -rf "$probe"
    echo "fuzz: skipped: clang++ cannot link libFuzzer (install libclang-rt-14-dev: scripts/setup.sh --extra)" >&2
    return 0
  fi
  rm -rf "$probe"

  cmake -S fuzz -B build-fuzz -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  local targets=()
  for reader in "${readers[@]}"; do targets+=("fuzz_$reader"); done
  cmake --build build-fuzz -j"$jobs" --target "${targets[@]}"
  for reader in "${readers[@]}"; do
    local corpus=build-fuzz/corpus/$reader artifacts=build-fuzz/artifacts/$reader
    mkdir -p "$corpus" "$artifacts"
    local seeds=("tests/fuzz/corpus/$reader")
    [ -d "tests/fuzz/regressions/$reader" ] && seeds+=("tests/fuzz/regressions/$reader")
    local from_shared
    from_shared=$(seeds_from_shared "$reader")
    [ -n "$from_shared" ] && [ -d "$from_shared" ] && seeds+=("$from_shared")
    echo "fuzz: $reader for ${seconds} s (seeds: ${seeds[*]})" >&2
    # New inputs go to the first (writable) corpus folder; the others only seed it.
    if ! ASAN_OPTIONS="$asan_options" "build-fuzz/fuzz_$reader" "$corpus" "${seeds[@]}" -dict="fuzz/$reader.dict" "${seed_option[@]}" \
        -max_total_time="$seconds" -max_len=65536 -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
        -artifact_prefix="$artifacts/" -print_final_stats=1 2>"build-fuzz/$reader.log"; then
      tail -n 60 "build-fuzz/$reader.log" >&2
      echo "fuzz: $reader FAILED: the input is in $artifacts/ (keep it in tests/fuzz/regressions/$reader/ once fixed)" >&2
      status=1
    else
      grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "build-fuzz/$reader.log" | sed "s/^/fuzz: $reader /" >&2 || true
    fi
  done
}

run_sanitized_tests() {
  # No -Werror here: the sanitizer instrumentation makes GCC warn inside libstdc++ (<regex>: -Wmaybe-uninitialized).
  # -O1 -g1 (line tables only): a third of the compile time of -O2 -g under the sanitizers (identify.cpp: 62 s
  # against 185 s of CPU), with file:line in every report.
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
    -DFEEDID_SANITIZE=ON -DFEEDID_WERROR=OFF \
    -DFEEDID_BUILD_BENCH=OFF -DFEEDID_SHARED_DATA="$shared" >/dev/null
  cmake --build build-asan -j"$jobs" --target test_readers test_vendor_readers
  echo "asan: running the reader tests under AddressSanitizer + UBSan" >&2
  for tests in test_readers test_vendor_readers; do
    if ! ASAN_OPTIONS=abort_on_error=1:detect_leaks=1:$asan_options UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
        "build-asan/tests/$tests"; then
      echo "asan: the reader tests ($tests) FAILED under the sanitizers" >&2
      status=1
    fi
  done
}

case "$what" in
  all) run_fuzzers; run_sanitized_tests ;;
  fuzz) run_fuzzers ;;
  asan) run_sanitized_tests ;;
  *) echo "usage: scripts/fuzz.sh [all|fuzz|asan]" >&2; exit 2 ;;
esac
exit $status
