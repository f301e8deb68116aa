# The two commands of the README: `make demo` and `make test`. Both run the set-up first.
VENV ?= .venv
SEED ?= 0
QUESTION ?= What is on the desk in the office?

.PHONY: demo scene test setup lint bench

setup:
	@scripts/setup.sh

demo: setup
	$(VENV)/bin/efficienteqa ask "$(QUESTION)" --scene synthetic:$(SEED) --out out/demo

scene: setup
	$(VENV)/bin/efficienteqa scenes generate --seed $(SEED) --out out/scene

test: setup
	$(VENV)/bin/pytest -q

# ruff, mypy and the import contracts of docs/ARCHITECTURE.md (CI runs it beside the tests).
lint: setup
	$(VENV)/bin/ruff check src tests benchmarks experiments scripts
	$(VENV)/bin/mypy src
	$(VENV)/bin/lint-imports

bench: setup
	$(VENV)/bin/python -m benchmarks.render_bench
