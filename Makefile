# The two commands of the README: `make demo` and `make test`. Both run the set-up first.
VENV ?= .venv
SEED ?= 0

.PHONY: demo test setup lint bench

setup:
	@scripts/setup.sh

demo: setup
	$(VENV)/bin/efficienteqa scenes generate --seed $(SEED) --out out/demo

test: setup
	$(VENV)/bin/pytest -q

lint: setup
	$(VENV)/bin/ruff check src tests benchmarks

bench: setup
	$(VENV)/bin/python benchmarks/render_bench.py
