#!/usr/bin/env bash
# The evaluation behind the README's tables: every method on the first LIMIT questions
# of the synthetic split, the Z_th and K ablations, the Ray speed-up with cached model calls, and
# Blind on HM-EQA. Runs resume: re-running this script continues where it stopped.
#
#   LIMIT=10 OUT=out/eval experiments/eval_tables.sh   # then: efficienteqa report out/eval/syn-*
#
# Back-ends: the offline default stack (synthetic houses, semantic-sensor perception from object
# labels, Qwen2.5-Coder-1.5B on llama.cpp, MiniLM relevancy, LLM grouping, Qwen as the judge).
set -u
LIMIT=${LIMIT:-10}
OUT=${OUT:-out/eval}
EQA=${EQA:-.venv/bin/efficienteqa}
RAY_LIMIT=${RAY_LIMIT:-40}
# Synthetic runs are graded by the rule judge (no model) and, with JUDGE, by LLM-Match beside it
# (a later --judge in the arguments wins: the Ray runs below use none).
JUDGE=${JUDGE:-local:qwen2.5-coder-1.5b}
run() { echo "==> $*"; "$EQA" eval --dataset synthetic --relevancy minilm --judge "$JUDGE" "$@" || echo "failed: $*"; }

run --method efficienteqa --limit "$LIMIT" --out "$OUT/syn-efficienteqa"
run --method blind --limit "$LIMIT" --out "$OUT/syn-blind"
run --method explore-eqa-blackbox --limit "$LIMIT" --out "$OUT/syn-explore-eqa-blackbox"
run --method explore-eqa --limit "$LIMIT" --out "$OUT/syn-explore-eqa"
# The threshold that acts with the default gate is z_gated (--z-th is refused there).
for z in 2 3; do run --method efficienteqa --z-gated "$z" --limit "$LIMIT" --out "$OUT/syn-efficienteqa-zg$z"; done
for k in 1 3 10; do run --method efficienteqa --top-k "$k" --limit "$LIMIT" --out "$OUT/syn-efficienteqa-k$k"; done
# Ray, with every model call replayed from the cache: frontier-only makes one answer call per
# episode, so RAY_LIMIT episodes fill the cache quickly; then the same episodes with 1 and 2
# workers (no judge, so no call is left uncached).
run --method frontier-only --limit "$RAY_LIMIT" --judge none --out "$OUT/fill-frontier-only"
run --method frontier-only --limit "$RAY_LIMIT" --judge none --workers 1 --out "$OUT/ray-1-worker"
run --method frontier-only --limit "$RAY_LIMIT" --judge none --workers 2 --out "$OUT/ray-2-workers"
run --method frontier-only --limit "$LIMIT" --out "$OUT/syn-frontier-only"
run --method random --limit "$LIMIT" --out "$OUT/syn-random"
"$EQA" eval --method blind --dataset hm-eqa ${HM_EQA_PATH:+--hm-eqa-path "$HM_EQA_PATH"} \
  --out "$OUT/hm-eqa-blind" || echo "failed: hm-eqa blind"
