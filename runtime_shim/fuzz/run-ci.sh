#!/usr/bin/env bash
# Short deterministic libFuzzer run for CI: fixed seed and run count; one-case JUnit file.
# usage: run-ci.sh FUZZER CORPUS_DIR RUNS JUNIT_XML NAME   (as emulator/fuzz/run-ci.sh)
set -u
fuzzer=$1 corpus=$2 runs=$3 junit=$4 name=$5
log=$(mktemp)
"$fuzzer" -seed=1 -runs="$runs" -max_len=2048 -rss_limit_mb=1024 -print_final_stats=1 "$corpus" >"$log" 2>&1
rc=$?
execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
if [ $rc -eq 0 ]; then
  failure=""
  echo "$name: 1 passed, 0 failed (${execs:-?} executions, seed 1)"
else
  tail -40 "$log"
  failure="<failure message=\"fuzzer exited with $rc\"/>"
  echo "$name: 0 passed, 1 failed (${execs:-?} executions, seed 1)"
fi
cat >"$junit" <<XML
<?xml version="1.0" encoding="UTF-8"?>
<testsuite name="$name" tests="1" failures="$([ $rc -eq 0 ] && echo 0 || echo 1)">
  <testcase classname="$name" name="libfuzzer_${runs}_runs">$failure</testcase>
</testsuite>
XML
rm -f "$log"
exit $rc
