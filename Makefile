# polydem — the two set-up commands are `make demo` and `make test` (see README.md).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
TSTAMP := $(VENV)/.installed-test

.SECONDARY:  # keep the preparations (intermediate results of the pattern rules) for later runs
.PHONY: install install-test lint demo test bench bench-halo bench-memory bench-ranks bench-peers figures figures-runs figures-ch3 figures-ch5 figures-ch6 figures-ch7 figures-lh figures-coupling validate docs clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[mpi]'
	touch $(STAMP)

$(TSTAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(TSTAMP)

install: $(STAMP)

install-test: $(TSTAMP)

## demo: the main job -- the concrete panel in slow tension (thesis ch. 7): outputs/concrete_tension.h5,
## its summary (E, nu, tensile strength) and plots (stress-strain curve in N/mm^2, damage map)
demo: install
	$(BIN)/python -m pip install --quiet -e '.[mpi]'
	$(BIN)/polydem run scenarios/concrete_tension.toml -o outputs/concrete_tension.h5 --overwrite
	$(BIN)/polydem report outputs/concrete_tension.h5

## lint: ruff linter and formatter check (configured in pyproject.toml); part of make test
lint: install-test
	$(BIN)/ruff check polydem_cli tests
	$(BIN)/ruff format --check polydem_cli tests

## test: lint, then the whole test suite (physics checks, smoke runs of every scenario, CLI, sweeps on Dask)
## (TEST_WORKERS processes through pytest-xdist, one module per worker: the budget is ~10 minutes on 2 cores)
TEST_WORKERS ?= 2
test: lint
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile

## bench: particle-steps per second (1, 2, auto threads; 1 and 2 MPI ranks where a scene runs decomposed) -> outputs/bench.json
bench: install
	$(BIN)/python -m pip install --quiet -e '.[mpi]'
	$(BIN)/polydem bench --out outputs/bench.json

## bench-halo: ghosts per rank of a domain decomposition (engine/decompose.py) up to 10^7 particles, one MPI
## exchange between two ranks timed, the parallel efficiency projected -> outputs/bench_halo.json
bench-halo: install
	$(BIN)/python -m pip install --quiet -e '.[mpi]'
	$(BIN)/python -m polydem_cli.benchmarks.halo outputs/bench_halo.json

## bench-memory: what a decomposed run costs each rank besides its steps -- peak memory, set-up, halo messages and
## bytes per step, one redistribution -- for bonded specimens of 1e4 and 1e5 particles on 1, 2, 4, 8 ranks
## (polydem_cli/benchmarks/memory.py) -> outputs/bench_memory.json
bench-memory: install
	$(BIN)/python -m pip install --quiet -e '.[mpi]'
	$(BIN)/python -m polydem_cli.benchmarks.memory outputs/bench_memory.json

## bench-ranks: particle-steps per second of scenes decomposed over 1 and 2 MPI ranks (engine/distributed.py), one
## thread per rank, alternated, medians and per-round ratios; weak scaling -> outputs/bench_ranks.json
bench-ranks: install
	$(BIN)/python -m pip install --quiet -e '.[mpi]'
	$(BIN)/python -m polydem_cli.benchmarks.ranks outputs/bench_ranks.json

## bench-peers: polydem against LAMMPS (body/rounded/polygon hexagons; gran/hooke/history disks vs polydem 24-gons),
## one core each, then both codes on 1 and 2 MPI ranks (the mpi extra's mpiexec) -> outputs/bench_peers.json
bench-peers: install
	$(BIN)/python -m pip install --quiet -e '.[peers,mpi]'
	LD_LIBRARY_PATH=$(CURDIR)/$(VENV)/lib $(BIN)/python -m polydem_cli.benchmarks.peers outputs/bench_peers.json

## figures: reproduce the thesis figures -> outputs/figures/ and outputs/figures/INDEX.md (hours of CPU;
## polydem batch runs each target's scenarios, JOBS at a time, a run after the run it starts from, with one progress
## line and an ETA over the target and a summary; interrupted runs are resumed, finished ones reused).  figures-ch7 alone: about 18 h of
## one core, of which the two slow rate-dependent concrete runs (dt = 2e-9 s) take 14 h
# runs at a time in the figure targets (`make figures JOBS=2` on two free cores) and threads of each run
# (`THREADS=2`: one long run on both cores, e.g. the thesis-form slow ra runs)
JOBS ?= 1
THREADS ?= 1
CH5_RUNS := $(patsubst scenarios/ch5/%.toml,outputs/ch5/%.h5,$(filter-out scenarios/ch5/small_%,$(wildcard scenarios/ch5/*.toml)))

CH6_RUNS := outputs/ch6/nuts_defect.h5 outputs/ch6/nuts_perfect.h5
CH5_JOBS = $(foreach r,$(CH5_RUNS),scenarios/ch5/$(notdir $(basename $(r))).toml=$(r))
CH6_JOBS = $(foreach r,$(CH6_RUNS),scenarios/ch6/$(notdir $(basename $(r))).toml=$(r))

CH7_RUNS := outputs/ch7/concrete_tension.h5 outputs/ch7/concrete_compression.h5 \
	$(patsubst scenarios/ch7/%.toml,outputs/ch7/%.h5,$(filter-out scenarios/ch7/small_% scenarios/ch7/smoke_%,$(wildcard scenarios/ch7/*.toml)))
DIF_RATES := 1e-3,1e-2,2.5e-2,0.1,0.25,1,10
# the rate-independent beams at the fast rates: the part of the rise that is structural inertia
DIF_RATES_RU := 0.1,0.25,1,10

LH_RUNS := $(patsubst scenarios/lh/%.toml,outputs/lh/%.h5,$(wildcard scenarios/lh/load_*.toml scenarios/lh/rate_*.toml scenarios/lh/relax_*.toml))

# cheapest first, chapter 7 (with the two 2e-9 s thesis-form runs, most of the CPU) last — with JOBS=1.  With
# JOBS > 1 the two slow runs start first: each holds one slot for hours while the other slots take the rest
# cheapest first; started last, they would run alone at the end with the other cores idle (about 2 h longer on two
# cores).  figures-runs runs every
# scenario behind a figure as one batch (one progress line and one ETA over all of them); the chapter targets
# after it find their runs finished.  Use JOBS=2, not make -j2 (two batches would race for the same results).
# (sub-makes in sequence: make may otherwise take the prerequisites of one rule in another order; the exit status
# says whether anything failed, the index is written in any case).  Each chapter target draws what its finished
# runs allow even when one of its runs failed or is still held by another process (the studies leave a missing run
# out and say so), and exits 1 if anything failed.
figures: install
	@st=0; \
	$(MAKE) --no-print-directory figures-ch3 figures-coupling || st=1; \
	$(MAKE) --no-print-directory figures-runs || st=1; \
	$(MAKE) --no-print-directory figures-lh figures-ch5 figures-ch6 figures-ch7 || st=1; \
	$(BIN)/polydem study index --figures outputs/figures; \
	exit $$st

## figures-runs: every scenario run behind the thesis figures, as one batch (LH, ch5, ch6, ch7; resumable)
figures-runs: install
	$(BIN)/polydem batch -j $(JOBS) --threads $(THREADS) \
		$(if $(SLOW_FIRST),$(CH7_SLOW_JOBS) $(LH_JOBS) $(CH5_JOBS) $(CH6_JOBS) $(CH7_REST_JOBS),$(LH_JOBS) $(CH5_JOBS) $(CH6_JOBS) $(CH7_JOBS))
	$(BIN)/polydem study index --figures outputs/figures

figures-ch3: install
	$(BIN)/polydem study integrators --out outputs/figures/ch3

outputs/ch5/%.h5: scenarios/ch5/%.toml $(STAMP)
	$(BIN)/polydem run $< -o $@ --continue

figures-ch5: install
	@st=0; \
	$(BIN)/polydem batch -j $(JOBS) --threads $(THREADS) $(CH5_JOBS) || st=1; \
	$(BIN)/polydem study ch5 --runs outputs/ch5 --out outputs/figures/ch5 || st=1; \
	exit $$st

outputs/ch6/%.h5: scenarios/ch6/%.toml $(STAMP)
	$(BIN)/polydem run $< -o $@ --continue

# Fig. 6.6: close-up of the defect; marked: the nuts in the columns of the two missing ones, two rows above
# and two rows below the defect row (the thesis's four marked nuts are in an unavailable figure, O-3)
figures-ch6: install
	@st=0; \
	$(BIN)/polydem batch -j $(JOBS) --threads $(THREADS) $(CH6_JOBS) || st=1; \
	$(BIN)/polydem report outputs/ch6/nuts_defect.h5 --out outputs/figures/ch6 --times 0,12.9,19.4 || st=1; \
	$(BIN)/polydem report outputs/ch6/nuts_defect.h5 --out outputs/figures/ch6 --times 0,12.9,19.4 \
		--region 2.5,10.2,1.6,9.4 --mark 5.715,7.699 --mark 6.985,7.699 --mark 5.715,3.3 --mark 6.985,3.3 || st=1; \
	$(BIN)/polydem report outputs/ch6/nuts_perfect.h5 --out outputs/figures/ch6 --times 5.9,20.2,22.4,41.2 || st=1; \
	exit $$st

outputs/ch7/concrete_%.h5: scenarios/concrete_%.toml $(STAMP)
	$(BIN)/polydem run $< -o $@ --continue

outputs/ch7/%.h5: scenarios/ch7/%.toml $(STAMP)
	$(BIN)/polydem run $< -o $@ --continue

# the thesis-form slow ra runs (dt = 2e-9 s, 4-11 h each) last with JOBS=1, so that every other figure's runs come
# first; first with JOBS > 1 (see figures above)
CH7_SLOW := outputs/ch7/tension_slow_ra.h5 outputs/ch7/compression_slow_ra.h5
CH7_SLOW_JOBS := $(foreach r,$(CH7_SLOW),scenarios/ch7/$(notdir $(basename $(r))).toml=$(r))
CH7_REST_JOBS := scenarios/concrete_tension.toml=outputs/ch7/concrete_tension.h5 \
	scenarios/concrete_compression.toml=outputs/ch7/concrete_compression.h5 \
	$(foreach r,$(filter-out outputs/ch7/concrete_% $(CH7_SLOW),$(CH7_RUNS)),scenarios/ch7/$(notdir $(basename $(r))).toml=$(r))
SLOW_FIRST = $(filter-out 1,$(JOBS))
CH7_JOBS = $(if $(SLOW_FIRST),$(CH7_SLOW_JOBS) $(CH7_REST_JOBS),$(CH7_REST_JOBS) $(CH7_SLOW_JOBS))

figures-ch7: install
	@st=0; \
	$(BIN)/polydem batch -j $(JOBS) --threads $(THREADS) $(CH7_JOBS) || st=1; \
	$(BIN)/polydem study dif scenarios/ch7/tension_slow_ra_filtered.toml --rates $(DIF_RATES) \
		--reference outputs/ch7/concrete_tension.h5 --out outputs/figures/ch7/dif_tension_filtered || st=1; \
	$(BIN)/polydem study dif scenarios/ch7/compression_slow_ra_filtered.toml --rates $(DIF_RATES) \
		--reference outputs/ch7/concrete_compression.h5 --out outputs/figures/ch7/dif_compression_filtered || st=1; \
	$(BIN)/polydem study dif scenarios/concrete_tension.toml --rates $(DIF_RATES_RU) \
		--reference outputs/ch7/concrete_tension.h5 --out outputs/figures/ch7/dif_tension_ru || st=1; \
	$(BIN)/polydem study dif scenarios/concrete_compression.toml --rates $(DIF_RATES_RU) \
		--reference outputs/ch7/concrete_compression.h5 --out outputs/figures/ch7/dif_compression_ru || st=1; \
	$(BIN)/polydem study ch7 --runs outputs/ch7 --out outputs/figures/ch7 || st=1; \
	$(BIN)/polydem study ch7 --runs outputs/ch7 --out outputs/figures/ch7/filtered --variant _filtered || st=1; \
	exit $$st

# Luding & Herrmann biaxial box: two preparations (about 6 min of one core each), ten loading runs from them,
# three more loading rates (Fig. 1.5) and seven relaxation runs (Fig. 1.4), 1-3 min each
outputs/lh/prepare_%.h5: scenarios/lh/prepare_%.toml $(STAMP)
	$(BIN)/polydem run $< -o $@ --continue

outputs/lh/load_p100_%.h5: scenarios/lh/load_p100_%.toml outputs/lh/prepare_p100.h5
	$(BIN)/polydem run $< -o $@ --continue

outputs/lh/prepare_p100_from_p500.h5: scenarios/lh/prepare_p100_from_p500.toml outputs/lh/prepare_p500.h5
	$(BIN)/polydem run $< -o $@ --continue

outputs/lh/load_p100u_%.h5: scenarios/lh/load_p100u_%.toml outputs/lh/prepare_p100_from_p500.h5
	$(BIN)/polydem run $< -o $@ --continue

outputs/lh/load_p500_%.h5: scenarios/lh/load_p500_%.toml outputs/lh/prepare_p500.h5
	$(BIN)/polydem run $< -o $@ --continue

outputs/lh/rate_%.h5: scenarios/lh/rate_%.toml outputs/lh/prepare_p500.h5
	$(BIN)/polydem run $< -o $@ --continue

outputs/lh/relax_%.h5: scenarios/lh/relax_%.toml outputs/lh/prepare_p100.h5
	$(BIN)/polydem run $< -o $@ --continue

LH_PREP := prepare_p100 prepare_p500 prepare_p100_from_p500
LH_JOBS := $(foreach p,$(LH_PREP),scenarios/lh/$(p).toml=outputs/lh/$(p).h5) \
	$(foreach r,$(LH_RUNS),scenarios/lh/$(notdir $(basename $(r))).toml=$(r))

figures-lh: install
	@st=0; \
	$(BIN)/polydem batch -j $(JOBS) --threads $(THREADS) $(LH_JOBS) || st=1; \
	$(BIN)/polydem study lh --runs outputs/lh --out outputs/figures/lh || st=1; \
	$(BIN)/polydem study lh --runs outputs/lh --out outputs/figures/lh --variant u || st=1; \
	exit $$st

# Sorg (2014): the four plates with a rhombus hole, adaptive FEM-lattice against fully resolved (a few minutes)
figures-coupling: install
	$(BIN)/polydem study coupling --width 80 --rows 48 --out outputs/figures/coupling

## validate: the thesis concrete and the calibrated C30/37 beside Kupfer's biaxial envelope, Bazant's size effect,
## Hordijk's softening and Petersson's beam (polydem study validate; docs/validation.md: wall time, results)
## -> outputs/figures/validate/ and outputs/figures/validate_c30_37/ (finished runs reused, interrupted ones resumed;
## JOBS runs at a time, RANKS MPI ranks each)
RANKS ?= 1
validate: install
	$(BIN)/polydem study validate --out outputs/figures/validate -j $(JOBS) --threads $(THREADS) --ranks $(RANKS)
	$(BIN)/polydem study validate --material scenarios/lab/c30_37_calibrated.toml --out outputs/figures/validate_c30_37 \
		-j $(JOBS) --threads $(THREADS) --ranks $(RANKS)

## docs: regenerate the scenario reference from the schema and the Python API's reference (docs/api.md)
docs: install
	$(BIN)/polydem schema --out docs/scenario.md
	$(BIN)/polydem schema --kind quasistatic --out docs/scenario_quasistatic.md
	$(BIN)/python -m polydem_cli.api --out docs/api.md

clean:
	rm -rf $(VENV) build *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
