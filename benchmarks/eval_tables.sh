#!/usr/bin/env bash
# The evaluation behind the README's tables (issue 6): every method on the first LIMIT questions
# of the synthetic split, the Z_th and K ablations, the Ray speed-up with cached model calls, and
# Blind on HM-EQA. Runs resume: re-running this script continues where it stopped.
#
#   LIMIT=10 OUT=out/eval benchmarks/eval_tables.sh   # then: efficienteqa report out/eval/syn-*
#
# Back-ends: the offline default stack (synthetic houses, semantic-sensor perception from object
# labels, Qwen2.5-Coder-1.5B on llama.cpp, MiniLM relevancy, LLM grouping, Qwen as the judge).
set -u
LIMIT=${LIMIT:-10}
OUT=${OUT:-out/eval}
EQA=${EQA:-.venv/bin/efficienteqa}
run() { echo "==> $*"; "$EQA" eval --dataset synthetic --limit "$LIMIT" --relevancy minilm "$@" || echo "failed: $*"; }

run --method efficienteqa --out "$OUT/syn-efficienteqa"
run --method blind --out "$OUT/syn-blind"
run --method explore-eqa-blackbox --out "$OUT/syn-explore-eqa-blackbox"
run --method explore-eqa --out "$OUT/syn-explore-eqa"
for z in 1 2; do run --method efficienteqa --z-th "$z" --out "$OUT/syn-efficienteqa-z$z"; done
for k in 1 3 10; do run --method efficienteqa --top-k "$k" --out "$OUT/syn-efficienteqa-k$k"; done
# Ray: the same episodes again, every model call and grade now in the caches.
run --method efficienteqa --workers 1 --out "$OUT/ray-1-worker"
run --method efficienteqa --workers 2 --out "$OUT/ray-2-workers"
run --method frontier-only --out "$OUT/syn-frontier-only"
run --method random --out "$OUT/syn-random"
"$EQA" eval --method blind --dataset hm-eqa ${HM_EQA_PATH:+--hm-eqa-path "$HM_EQA_PATH"} \
  --out "$OUT/hm-eqa-blind" || echo "failed: hm-eqa blind"
