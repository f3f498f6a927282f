# Two entry points on a fresh machine: `make demo` and `make test`.
# Both create .venv (if missing) and install the package into it first.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# worker processes of `make demo`'s solve (the problems are independent)
JOBS   ?= 2

.PHONY: demo studies test bench clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/python -m compileall -q src   # an editable install compiles nothing: ~0.1 s per CLI run otherwise
	@touch $(STAMP)

# exit 1 from solve means "some design is not optimal": two examples are infeasible on purpose
# (tilt_spring_arm: springs cannot follow a tilting base; yasir2019_holder: the paper's design
# of the whole holder), and their reports say why; any other status stops make
demo: $(STAMP)
	$(BIN)/counterpoise solve problems/*.toml --out results --plot --jobs $(JOBS) || [ $$? -eq 1 ]

# the committed studies in results/: the Pareto front of the free-extensions leg, a
# 1000-point payload sweep of the hybrid (docs/studies.md), the tilting-base trade-off
# of the hybrid arm (docs/tilt.md) and the whole holder's residual against the leg planes'
# tilt (docs/seeds.md#yasir-holder)
studies: $(STAMP)
	$(BIN)/counterpoise study problems/yasir2019_free_extensions.toml --vary 'inertia_weight=0 1/m^2:400 1/m^2:41' --out results
	$(BIN)/counterpoise study problems/yasir2019_hybrid.toml --vary 'm_endo=400 g:1000 g:1000' --out results
	$(BIN)/python scripts/tilt_tradeoff.py results/tilt_hybrid_arm-tradeoff
	$(BIN)/counterpoise study problems/yasir2019_holder.toml --vary 'tilt=1 deg:15 deg:8' --out results

# type check first (docs/development.md: the settings are [tool.mypy] in pyproject.toml), then the suite
test: $(STAMP)
	$(BIN)/python -m mypy
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_solve.py
	$(BIN)/python benchmarks/bench_scaling.py

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .hypothesis
