#!/usr/bin/env bash
# Runs every fuzz target for SECONDS seconds on its corpus (fuzz/README.md); SECONDS 0 replays the
# committed corpus once without mutation, then, when FUZZ_RUNS=N is set, mutates it for N more
# inputs with a fixed seed (deterministic: the same inputs on every run of the same build;
# what CI runs).
#   bash fuzz/run.sh BUILD_FUZZ_DIR [SECONDS] [TARGET...]
#   FUZZ_RUNS=3000 bash fuzz/run.sh BUILD_FUZZ_DIR 0
# The committed corpus fuzz/corpus/T is read only: new inputs go to a temporary directory that
# is removed afterwards (a long local session keeps them: see fuzz/README.md). A finding (crash,
# leak, timeout, contract violation) is saved as fuzz/findings/T-<kind>-<hash> and fails the run.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
bin="${1:?usage: fuzz/run.sh BUILD_FUZZ_DIR [SECONDS] [TARGET...]}"
seconds="${2:-20}"
shift 2 || shift $#
targets=("$@")
# (the longest first: two cores finish together)
if [ ${#targets[@]} -eq 0 ]; then targets=(cell mapping krl krl_config robot measurements mesh urdf rapid urscript xml_program); fi
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}"
# leaks inside assimp itself (not accura's; findings/README.md) are suppressed
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$here/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
# The strict contract (fuzz_util.h: every error says what was expected, at line:column or, in a
# binary mesh, a byte offset) is enforced for every target but those listed in FUZZ_LENIENT
# (default: none; fuzz/findings/README.md lists what was found and fixed). FUZZ_STRICT=0 turns it
# off.
strict="${FUZZ_STRICT:-1}"
lenient=" ${FUZZ_LENIENT-} "
# One target: replay (and mutate) or a timed run; prints its lines, returns 1 on a finding.
run_target() {
  local t="$1" status=0 work scratch start runs corpus_size
  local dict=()
  if [ "$strict" = 1 ] && [[ "$lenient" != *" $t "* ]]; then export FUZZ_STRICT=1; else export FUZZ_STRICT=0; fi
  work="$(mktemp -d "$out/work.XXXXXX")"
  # the target's scratch files go here: a fuzzer that dies on a finding cannot remove its own
  scratch="$(mktemp -d "$out/scratch.XXXXXX")"
  mkdir -p "$here/findings"
  [ -f "$here/dict/$t.dict" ] && dict=(-dict="$here/dict/$t.dict")
  start=$(date +%s)
  if [ "$seconds" -eq 0 ]; then
    corpus_size=$(ls "$here/corpus/$t" | wc -l)
    runs="${FUZZ_RUNS:-0}"
    if [ "$runs" -gt 0 ]; then
      # N mutated inputs beyond the corpus (libFuzzer's -runs counts the corpus too), seed 1;
      # libFuzzer first runs every corpus input once (the replay: its log says INITED when that
      # is done), then mutates. New inputs go to $work (removed), a finding to fuzz/findings/ as
      # in a timed run. (One process: a replay of its own before it ran every input twice.)
      mkdir -p "$work"
      if TMPDIR="$scratch" "$bin/fuzz_$t" "$work" "$here/corpus/$t" "${dict[@]}" -seed=1 -runs=$((corpus_size + runs)) \
           -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 -artifact_prefix="$here/findings/$t-" \
           >"$work.log" 2>&1; then
        echo "fuzz_$t: replayed $corpus_size corpus inputs, then $runs mutated inputs (seed 1) in $(( $(date +%s) - start )) s, ok, $(grep -o 'cov: [0-9]*' "$work.log" | tail -1)"
      elif grep -q 'INITED' "$work.log"; then
        echo "fuzz_$t: FINDING among the mutated inputs (saved under fuzz/findings/); the end of its log:"
        tail -40 "$work.log"
        status=1
      else
        echo "fuzz_$t: FINDING while replaying the corpus (saved under fuzz/findings/); the end of its log:"
        tail -40 "$work.log"
        status=1
      fi
    # replay: every committed corpus input once, no mutation (deterministic)
    elif TMPDIR="$scratch" "$bin/fuzz_$t" -runs=0 -timeout=10 -rss_limit_mb=2048 "$here/corpus/$t" >"$work.log" 2>&1; then
      echo "fuzz_$t: replayed $corpus_size corpus inputs, ok"
    else
      echo "fuzz_$t: FINDING while replaying the corpus; the end of its log:"
      tail -40 "$work.log"
      status=1
    fi
    rm -rf "$work" "$work.log" "$scratch"
    return $status
  fi
  if TMPDIR="$scratch" "$bin/fuzz_$t" "$work" "$here/corpus/$t" "${dict[@]}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
       -max_len=65536 -print_final_stats=1 -artifact_prefix="$here/findings/$t-" >"$work.log" 2>&1; then
    echo "fuzz_$t: ok, $(grep -o 'stat::number_of_executed_units: *[0-9]*' "$work.log" | grep -o '[0-9]*$') runs in $(( $(date +%s) - start )) s, $(grep -o 'cov: [0-9]*' "$work.log" | tail -1)"
  else
    echo "fuzz_$t: FINDING (saved under fuzz/findings/); the end of its log:"
    tail -40 "$work.log"
    status=1
  fi
  rm -rf "$work" "$work.log" "$scratch"
  return $status
}

# The targets run side by side, JOBS at a time (default: the cores; each libFuzzer process is
# single-threaded: with SECONDS 0 the inputs, seeded, do not depend on JOBS; a timed run's count
# of inputs does, as the targets share the cores); each one's lines are printed in the order of
# the list when it ends.
jobs_max="${JOBS:-$(nproc)}"
if ! [[ "$jobs_max" =~ ^[1-9][0-9]*$ ]]; then
  echo "fuzz/run.sh: JOBS: expected a whole number of targets at a time (>= 1), found '$jobs_max'" >&2
  exit 2
fi
# every target's logs, work and scratch directories under one directory, removed at the end; each
# target in a process group of its own (set -m), so that an interrupted run stops its fuzzers too
out="$(mktemp -d)"
stop() {
  for p in $(jobs -p); do kill -TERM -- "-$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$out"
}
trap 'rm -rf "$out"' EXIT
trap 'stop; exit 130' INT TERM
set -m
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n || true; done
  ( set +e; run_target "$t" >"$out/$t.log" 2>&1; echo $? >"$out/$t.rc" ) &
done
wait
status=0
for t in "${targets[@]}"; do
  cat "$out/$t.log"
  [ "$(cat "$out/$t.rc" 2>/dev/null)" = 0 ] || status=1
done
exit $status
