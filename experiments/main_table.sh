#!/usr/bin/env bash
# The main table (docs/RESULTS.md): every method of DESIGN 3.6 on the same questions and start
# poses, the first LIMIT questions of the synthetic split (8 per category for 48; houses 100-999,
# never used for tuning), graded by the rule judge and by JUDGE's LLM-Match beside it (JUDGE=none:
# the rule judge only); then the table with paired differences against white-box ExploreEQA.
# Runs resume: re-running continues (a run graded later by `efficienteqa judge` resumes too).
#
#   LIMIT=48 OUT=results/main-heldout experiments/main_table.sh
#
# DATASET: another question set (e.g. synthetic:0-3). ARGS go to every `efficienteqa eval` (the CI test passes the small model and tiny episodes).
# Back-ends: the offline default stack unless ARGS say otherwise (synthetic houses, semantic-
# sensor perception from object labels, Qwen2.5-Coder-1.5B on llama.cpp, MiniLM relevancy).
set -u
LIMIT=${LIMIT:-48}
DATASET=${DATASET:-synthetic}
OUT=${OUT:-results/main-heldout}
EQA=${EQA:-.venv/bin/efficienteqa}
JUDGE=${JUDGE:-local:qwen2.5-coder-1.5b}
read -r -a ARGS <<< "${ARGS:-}"
status=0
run() {
  name=$1; shift
  echo "==> $name $(date +%T)"
  "$EQA" eval --dataset "$DATASET" --limit "$LIMIT" --out "$OUT/$name" --judge "$JUDGE" "$@" "${ARGS[@]}" || { echo "failed: $name"; status=1; }
}
# Each row is a named configuration shipped with the package (src/efficienteqa/config/toml/NAME.toml,
# which says what it holds); ARGS, given after it, win. The paper row is the paper's algorithm on
# the offline stack (paper-offline: DESIGN 3.2-3.5 with every option beyond the paper off).
run default --preset default
run explore-eqa --preset explore-eqa
run explore-eqa-blackbox --preset explore-eqa-blackbox
run explore-eqa-verbalized-prompt --preset explore-eqa-verbalized-prompt
run explore-eqa-per-token --preset explore-eqa-per-token
run frontier-only --preset frontier-only
run random --preset random
run blind --preset blind
run paper-offline --preset paper-offline
run pixels --preset pixels
run paper-offline-pixels --preset paper-offline-pixels
RUNS=("$OUT/default" "$OUT/pixels" "$OUT/paper-offline" "$OUT/paper-offline-pixels" "$OUT/explore-eqa" "$OUT/explore-eqa-blackbox"
      "$OUT/explore-eqa-verbalized-prompt" "$OUT/explore-eqa-per-token" "$OUT/frontier-only"
      "$OUT/random" "$OUT/blind")
"$EQA" report "${RUNS[@]}" --paired-against "$OUT/explore-eqa" --markdown || status=1
exit $status
