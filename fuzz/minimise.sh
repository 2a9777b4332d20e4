#!/usr/bin/env bash
# Rewrites fuzz/corpus/TARGET as the smallest set of inputs (libFuzzer's
# -merge) with all the coverage of fuzz/work/TARGET, the seeds and the old
# corpus. Usage: fuzz/minimise.sh TARGET
set -euo pipefail
cd "$(dirname "$0")/.."
t=$1
new=$(mktemp -d)
trap 'rm -rf "$new"' EXIT
mkdir -p "fuzz/work/$t" "fuzz/seeds/$t" "fuzz/corpus/$t"
cargo +nightly fuzz build -s none "$t"
"fuzz/target/x86_64-unknown-linux-gnu/release/$t" -merge=1 -max_len=16384 -timeout=5 \
  "$new" "fuzz/corpus/$t" "fuzz/work/$t" "fuzz/seeds/$t" 2>&1 | grep -E 'MERGE-OUTER' | tail -n 3
rm -rf "fuzz/corpus/$t"
mkdir -p "fuzz/corpus/$t"
cp "$new"/* "fuzz/corpus/$t/"
echo "fuzz/corpus/$t: $(ls "fuzz/corpus/$t" | wc -l) files, $(du -sh "fuzz/corpus/$t" | cut -f1)"
