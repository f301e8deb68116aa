# The two commands of the README: `make demo` and `make test`. Both run the set-up first: the
# demo's (`setup`), or with the developers' tools, chromium and the test extras (`setup-dev`).
VENV ?= .venv
SEED ?= 0
QUESTION ?= What is on the desk in the office?

.PHONY: demo scene test setup setup-dev lint bench

setup:
	@scripts/setup.sh

setup-dev:
	@scripts/setup.sh --dev

demo: setup
	$(VENV)/bin/efficienteqa ask "$(QUESTION)" --scene synthetic:$(SEED) --out out/demo --overwrite

scene: setup
	$(VENV)/bin/efficienteqa scenes generate --seed $(SEED) --out out/scene

# One worker a core (pytest-xdist; idle workers take tests from busy ones): every test, the fault
# suite (tests/faults) and the slow ones included.
test: setup-dev
	$(VENV)/bin/pytest -q -n auto --dist worksteal

# ruff, mypy and the import contracts of docs/ARCHITECTURE.md (CI runs it beside the tests).
lint: setup-dev
	$(VENV)/bin/ruff check src tests benchmarks experiments scripts examples
	$(VENV)/bin/mypy src
	$(VENV)/bin/lint-imports

bench: setup
	$(VENV)/bin/python -m benchmarks.render_bench
