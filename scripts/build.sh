#!/usr/bin/env bash
# Configures and builds accura (Release) in build/. Used by example.sh (only the targets given:
# `build.sh accura`, the command, not the tests and benchmarks) and test.sh (everything).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE=Release -DACCURA_UNITY_BUILD=ON >/dev/null
targets=()
for t in "$@"; do targets+=(--target "$t"); done
cmake --build "$root/build" -j"$(nproc)" "${targets[@]}"
