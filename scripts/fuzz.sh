#!/usr/bin/env bash
# Fuzzes the .nbtf reader (and what `nbtf info` / NbtfDecoder do with a file that parses)
# with libFuzzer + AddressSanitizer + UndefinedBehaviorSanitizer + LeakSanitizer.
#   scripts/fuzz.sh [SECONDS]    default 600
# Builds fuzz/ with clang into build-fuzz/, copies the seed corpus (fuzz/corpus/, valid
# .nbtf files) to build-fuzz/run/corpus/ and fuzzes for SECONDS. Inputs that crash, leak,
# time out or trip a sanitizer are saved to build-fuzz/run/artifacts/; replay one with
#   build-fuzz/nbtf_reader_fuzzer build-fuzz/run/artifacts/crash-...
# Ends with one line: bench fuzz_nbtf_reader: ... PASS|FAIL. See docs/reliability.md.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
seconds=${1:-600}
[[ "$seconds" =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: SECONDS must be a positive integer, got '$seconds'" >&2; exit 2; }

# clang 14 and its runtime libraries (libclang_rt.fuzzer / asan / ubsan) from Debian.
"$root/scripts/setup.sh" --with clang-14 --with libclang-rt-14-dev
build=$root/build-fuzz
cmake -S "$root/fuzz" -B "$build" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=None >/dev/null
cmake_build "$build"

run=$build/run
rm -rf "$run"
mkdir -p "$run/corpus" "$run/artifacts"
cp "$root"/fuzz/corpus/* "$run/corpus/"
log=$run/fuzz.log
echo "fuzz: $(ls "$run/corpus" | wc -l) seed files, $seconds s, log $log"

# halt_on_error + abort: the first report stops the run and libFuzzer saves the input.
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:allocator_may_return_null=0:detect_stack_use_after_return=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:abort_on_error=1
start=$(date +%s.%N)
set +e
"$build/nbtf_reader_fuzzer" "$run/corpus" -max_total_time="$seconds" -detect_leaks=1 -timeout=10 \
  -rss_limit_mb=2048 -max_len=16384 -print_final_stats=1 -artifact_prefix="$run/artifacts/" >"$log" 2>&1
rc=$?
set -e
elapsed=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.0f", e - s }')
tail -n 15 "$log"

execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
execs=${execs:-0}
crashes=$(find "$run/artifacts" -type f | wc -l)
reports=$(grep -cE 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:|deadly signal|uncaught exception' "$log" || true)
status=PASS
if [[ $rc -ne 0 || $crashes -ne 0 || $reports -ne 0 || $elapsed -lt $seconds ]]; then status=FAIL; fi
[[ $crashes -ne 0 ]] && echo "fuzz: saved inputs: $(ls "$run/artifacts")"
echo "bench fuzz_nbtf_reader: $execs execs in $elapsed s, $crashes crashes (target $seconds s, no crash/leak/sanitizer report) $status"
[[ $status == PASS ]]
