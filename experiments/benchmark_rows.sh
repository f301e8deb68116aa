#!/usr/bin/env bash
# The leaderboard of docs/benchmark.md: methods on the held-out test split synthetic-test-v1 (120
# questions on houses 5000-5039, never used for tuning), graded by the rule judge (exact on these
# questions; no model), from one clean commit. Runs resume: re-running continues.
#
#   OUT=results/benchmark experiments/benchmark_rows.sh
#
# Back-ends: the offline default stack (synthetic houses, semantic-sensor perception from object
# labels, Qwen2.5-Coder-1.5B on llama.cpp, MiniLM relevancy), pixels with its preset. ARGS go to
# every `efficienteqa eval`.
set -u
OUT=${OUT:-results/benchmark}
EQA=${EQA:-.venv/bin/efficienteqa}
read -r -a ARGS <<< "${ARGS:-}"
status=0
for row in blind frontier-only default; do
  echo "==> $row $(date +%T)"
  "$EQA" eval --preset "$row" --eval.dataset synthetic-test --eval.judge rule \
    --out "$OUT/$row" "${ARGS[@]}" || { echo "failed: $row"; status=1; }
done
"$EQA" report "$OUT/default" "$OUT/frontier-only" "$OUT/blind" --paired-against "$OUT/default" \
  --markdown || status=1
exit $status
