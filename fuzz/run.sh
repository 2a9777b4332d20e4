#!/usr/bin/env bash
# Fuzzes one target for SECONDS on one core, growing fuzz/work/TARGET from
# the seeds (fuzz/seed.sh) and the committed corpus; the log (each line
# stamped with the Unix time) goes to fuzz/work/TARGET.log. Afterwards `fuzz/minimise.sh TARGET` rewrites
# fuzz/corpus/TARGET. Usage: fuzz/run.sh TARGET SECONDS [libFuzzer flags]
set -euo pipefail
cd "$(dirname "$0")/.."
t=$1 secs=$2
shift 2
mkdir -p "fuzz/work/$t" "fuzz/corpus/$t" "fuzz/seeds/$t" "fuzz/artifacts/$t"
dict=()
[ -f "fuzz/dict/$t.dict" ] && dict=("-dict=fuzz/dict/$t.dict")
cargo +nightly fuzz run -s none "$t" "fuzz/work/$t" "fuzz/corpus/$t" "fuzz/seeds/$t" -- \
  -max_total_time="$secs" -timeout=5 -rss_limit_mb=2048 -max_len=16384 \
  -print_final_stats=1 "${dict[@]}" "$@" 2>&1 |
  # Each line stamped with the Unix time (when coverage stopped growing).
  while IFS= read -r l; do printf '%(%s)T %s\n' -1 "$l"; done |
  tee -a "fuzz/work/$t.log" | grep -E --line-buffered 'INITED|DONE|ERROR|panicked|stat::|Test unit' | tail -n 20
