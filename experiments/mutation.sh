#!/usr/bin/env bash
# Mutation benchmark, not a CI step: mutmut mutates the stop module (stop/), the VC
# parsers (vc/parse.py, numbers.py, yes_no.py, json_reply.py), the RAG answer (answer/rag.py)
# and the judge (eval/judge.py), runs each mutant against the fast tests that reach it
# ([tool.mutmut] in pyproject.toml) and prints, per file, the share of mutants killed: a test
# failed (or timed out) with the mutation in place.
#
#   experiments/mutation.sh                          # all these files
#   experiments/mutation.sh "efficienteqa.stop.*"    # only mutants whose names match (mutmut run's patterns)
#
# JOBS (default 2) mutants run at once. Working files go to mutants/ (git-ignored), made afresh
# each run; mutmut's own log is mutants/run.log, and `mutmut results` / `mutmut show NAME` list
# and show the survivors afterwards.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
[ -x "$VENV/bin/mutmut" ] || { echo "mutmut is missing: $VENV/bin/pip install -e '.[dev]'" >&2; exit 1; }
rm -rf mutants
log=$(mktemp)
start=$(date +%s)
if ! "$VENV/bin/mutmut" run --max-children "${JOBS:-2}" "$@" >"$log" 2>&1; then
    tail -n 30 "$log" >&2
    echo "mutmut failed; its log is $log" >&2
    exit 1
fi
mkdir -p mutants && mv "$log" mutants/run.log
echo "mutation benchmark: $(( $(date +%s) - start )) s, JOBS=${JOBS:-2}"
"$VENV/bin/python" - <<'PY'
import json
from pathlib import Path

KILLED = {1, 3}  # the tests failed (3: pytest's internal error)
TIMEOUT = {24, -24, 36, 152, 255}  # the tests ran past mutmut's time limit (an endless loop)
total = {"mutants": 0, "killed": 0}
for meta in sorted(Path("mutants").rglob("*.py.meta")):
    codes = [c for c in json.loads(meta.read_text())["exit_code_by_key"].values() if c is not None]
    if not codes:
        continue
    failed = sum(c in KILLED for c in codes)
    timeout = sum(c in TIMEOUT for c in codes)
    survived = sum(c == 0 for c in codes)
    untested = sum(c in (5, 33) for c in codes)
    killed = failed + timeout
    total["mutants"] += len(codes)
    total["killed"] += killed
    path = meta.relative_to("mutants").with_suffix("")
    print(f"{str(path):40s} killed {killed:4d} / {len(codes):4d} = {100 * killed / len(codes):5.1f} %"
          f"  (timeouts {timeout}, survived {survived}, no test reaches {untested})")
if total["mutants"]:
    print(f"{'all':40s} killed {total['killed']:4d} / {total['mutants']:4d} = "
          f"{100 * total['killed'] / total['mutants']:5.1f} %")
PY
