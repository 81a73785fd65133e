#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (build-fuzz/, SCULPT_FUZZ=ON) and runs each for
# SECONDS (default 60), starting from tests/fuzz/corpus/<target>/. Prints one summary line per
# target (executions, coverage) and exits non-zero if any target crashed, leaked or hit UB;
# the reproducer is left in build-fuzz/artifacts/<target>/. See docs/fuzzing.md.
# Needs Debian's clang (libclang-rt-*-dev ships libFuzzer): apt-get install clang.
set -euo pipefail
seconds="${1:-${FUZZ_SECONDS:-60}}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${SCULPT_FUZZ_BUILD:-$root/build-fuzz}"
# FUZZ_TARGETS="session leaf_records" runs (and builds) only those.
read -r -a targets <<<"${FUZZ_TARGETS:-frame stroke contour range_coder model edit_log server_config leaf_records session}"

# -O1 and line tables only: the OpenVDB-based libraries (levelset, server) are compiled here too,
# and full debug info of them costs minutes per file on a small machine.
cmake -S "$root" -B "$build" -DSCULPT_FUZZ=ON -DSCULPT_BUILD_TESTS=OFF \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -gline-tables-only -DNDEBUG" >/dev/null
cmake --build "$build" --target "${targets[@]/#/fuzz_}" -j"${JOBS:-2}"

# Per-target flags. session: its server and scene live for the whole process, so nearly every
# input ends with more allocations than frees (queues, histories, other threads' work) and
# libFuzzer's per-input leak check would re-run it and scan the heap each time; leaks are still
# reported by LeakSanitizer when the process exits (after the scenes are torn down).
declare -A extra=([session]="-detect_leaks=0")

failed=0
for t in "${targets[@]}"; do
  work="$build/corpus/$t"
  artifacts="$build/artifacts/$t/"
  mkdir -p "$work" "$artifacts"
  log="$build/fuzz_$t.log"
  # New inputs go to the work corpus; the committed seeds stay read-only input.
  # shellcheck disable=SC2086
  if "$build/bin/fuzz_$t" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 ${extra[$t]:-} \
      -artifact_prefix="$artifacts" -print_final_stats=1 \
      "$work" "$root/tests/fuzz/corpus/$t" >"$log" 2>&1; then
    status=ok
  else
    status="FAILED (see $log, reproducer in $artifacts)"
    failed=1
  fi
  runs=$(grep -Eo '^stat::number_of_executed_units: *[0-9]+' "$log" | grep -Eo '[0-9]+$' || true)
  cov=$(grep -Eo 'cov: [0-9]+' "$log" | tail -1 || true)
  printf '%-13s %5ss  execs=%-10s %-10s %s\n' "$t" "$seconds" "${runs:-?}" "${cov:-cov: ?}" "$status"
done
exit "$failed"
