#!/usr/bin/env bash
# Builds the firmware core's libFuzzer target (firmware/fuzz/fuzz_device.cpp) with
# ASan + UBSan and runs it for SECONDS (default 20). Corpus and crash artefacts live in
# firmware/build/fuzz/ (gitignored). Prints the executions done and any crash found;
# exits non-zero on a crash.
set -euo pipefail
SECONDS_TO_RUN="${1:-20}"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
FW="$ROOT/firmware"
OUT="$FW/build/fuzz"
mkdir -p "$OUT/corpus" "$OUT/artifacts"
CXX="${CXX_FUZZ:-clang++}"
"$CXX" -std=c++11 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
    -I"$FW" -I"$FW/core" -I"$FW/tests" \
    "$FW"/core/*.cpp "$FW/tests/fake_board.cpp" "$FW/fuzz/fuzz_device.cpp" \
    -o "$OUT/fuzz_device"
LOG="$OUT/last_run.log"
set +e
"$OUT/fuzz_device" "$OUT/corpus" -max_total_time="$SECONDS_TO_RUN" -max_len=2048 -timeout=20 \
    -artifact_prefix="$OUT/artifacts/" -print_final_stats=1 >"$LOG" 2>&1
STATUS=$?
set -e
EXECS="$(grep -E '^stat::number_of_executed_units' "$LOG" | awk '{print $2}')"
echo "fuzz_device: ${EXECS:-?} executions in ${SECONDS_TO_RUN} s, corpus $(ls "$OUT/corpus" | wc -l) inputs"
if [ "$STATUS" -ne 0 ]; then
    echo "fuzz_device: FAILED (exit $STATUS); crash input and log:"
    grep -E 'ERROR|invariant|SUMMARY|Test unit written' "$LOG" || tail -40 "$LOG"
    exit 1
fi
echo "fuzz_device: no crash"
