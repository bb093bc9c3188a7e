# polydem — the two set-up commands are `make demo` and `make test` (see README.md).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install demo test bench figures figures-ch3 figures-ch5 docs clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

## demo: run the default scenario, write outputs/demo.h5 and its plots
demo: install
	$(BIN)/polydem run scenarios/demo_hex_pile.toml -o outputs/demo.h5 --overwrite
	$(BIN)/polydem report outputs/demo.h5

## test: the whole test suite (fast physics checks, smoke runs, CLI)
test: install
	$(BIN)/python -m pytest -q

## bench: particle-steps per second -> outputs/bench.json
bench: install
	$(BIN)/polydem bench --out outputs/bench.json

## figures: reproduce the thesis figures -> outputs/figures/ (hours of CPU; `make -j2 figures` uses both
## cores; interrupted runs are resumed, finished ones are not repeated)
CH5_RUNS := $(patsubst scenarios/ch5/%.toml,outputs/ch5/%.h5,$(filter-out scenarios/ch5/small_%,$(wildcard scenarios/ch5/*.toml)))

figures: figures-ch3 figures-ch5

figures-ch3: install
	$(BIN)/polydem study integrators --out outputs/figures/ch3

outputs/ch5/%.h5: scenarios/ch5/%.toml $(STAMP)
	$(BIN)/polydem run $< -o $@ --continue

figures-ch5: install $(CH5_RUNS)
	$(BIN)/polydem study ch5 --runs outputs/ch5 --out outputs/figures/ch5

## docs: regenerate the scenario reference from the schema
docs: install
	$(BIN)/polydem schema --out docs/scenario.md

clean:
	rm -rf $(VENV) build *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
