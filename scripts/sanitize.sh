#!/usr/bin/env bash
# The hardening run (issue 14; fuzz/README.md): builds accura with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer, and the libFuzzer targets of fuzz/, in build-asan/; runs the
# whole test suite (ctest) under the sanitizers, then every fuzz target for FUZZ_SECONDS
# seconds (default 20) on its corpus. Any sanitizer report, test failure or fuzz finding fails
# the run. Used by .ci/run after scripts/test.sh.
#
#   FUZZ_SECONDS=0 bash scripts/sanitize.sh     # tests, then each corpus replayed once
#   FUZZ_SECONDS=0 FUZZ_RUNS=5000 bash scripts/sanitize.sh   # ... and 5000 mutated inputs each, seed 1 (CI)
#   JOBS=1 bash scripts/sanitize.sh             # build and test with one core
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${ACCURA_ASAN_BUILD:-$root/build-asan}"
jobs="${JOBS:-$(nproc)}"
fuzz_seconds="${FUZZ_SECONDS:-20}"
bash "$root/scripts/install-deps.sh"

launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache); fi
# -O1: the sanitizer build compiles about 40% faster than at -O2 and the suite still runs in
# minutes; -UNDEBUG (RelWithDebInfo without -DNDEBUG): Eigen's and the project's assertions on.
CC=clang CXX=clang++ cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 \
  -DACCURA_SANITIZE=ON -DACCURA_BUILD_FUZZ=ON -DACCURA_BUILD_BENCH=OFF -DACCURA_UNITY_BUILD=ON "${launcher[@]}" >/dev/null
cmake --build "$build" -j"$jobs"

# halt on the first report, with a stack trace; leaks are errors
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
(cd "$build" && ctest --output-on-failure -j"$jobs")

bash "$root/fuzz/run.sh" "$build/fuzz" "$fuzz_seconds"
