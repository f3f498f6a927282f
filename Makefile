# Two entry points on a fresh machine: `make demo` and `make test`.
# Both create .venv (if missing) and install the package into it first.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
# set-up stamps: the runtime (make demo) and the test tools on top of it (make test)
STAMP  := $(VENV)/.installed
TESTSTAMP := $(VENV)/.installed-test
DOCSTAMP := $(VENV)/.installed-docs
# worker processes of `make demo`'s solve (the problems are independent)
JOBS   ?= 2

.PHONY: demo studies synthesis test docs bench clean

# $(call install,ARGS): `pip install ARGS` into the venv, by uv where it can be had (uv on the
# PATH, else uv from PyPI put into the venv by $(PYTHON)'s pip): it resolves and installs in
# parallel and compiles nothing: a fresh clone installs ~8x faster than with pip (benchmarks/README.md).
# If uv cannot be had or fails, pip does the same install (pip put into the venv first), also
# without compiling (all of site-packages, 10,900 files, took 45 s CPU to compile; see demo:).
install = UV=$$(command -v uv || echo $(BIN)/uv); \
	{ test -x "$$UV" || $(PYTHON) -m pip --python $(BIN)/python install --quiet uv; } \
	&& "$$UV" pip install --quiet --python $(BIN)/python $(1) \
	|| { echo "make: uv could not be used; installing with pip (slower)" >&2; \
	     { $(BIN)/python -m pip --version >/dev/null 2>&1 || $(BIN)/python -m ensurepip --upgrade >/dev/null; } \
	     && $(BIN)/python -m pip install --quiet --no-compile $(1); }

# the runtime only (no [test] tools): a normal venv, pip included; the venv is made without
# pip (ensurepip alone takes ~15 s) and uv installs pip with the rest
$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv --without-pip $(VENV)
	@$(call install,-e . pip)
	$(BIN)/python -m compileall -q src   # an editable install compiles nothing: ~0.1 s per CLI run otherwise
	@# the libraries of a solve (numpy, matplotlib, pint, pydantic, casadi...) compiled by one small
	@# solve that keeps its .pyc: uv compiles nothing, and where PYTHONDONTWRITEBYTECODE is set every
	@# later process would compile them again (a single solve 1.9x the CPU; docs/performance.md)
	@tmp=$$(mktemp -d) && PYTHONDONTWRITEBYTECODE= COUNTERPOISE_CACHE=off $(BIN)/counterpoise solve problems/fourbar_springs.toml --out "$$tmp" --plot >/dev/null 2>&1; rm -rf "$$tmp"
	@touch $(STAMP)

# make test: the [test] extra (pytest, hypothesis, mypy and its stubs) on top of the runtime.
# The test tools and the libraries the tests import compiled once, keeping their .pyc (as the
# runtime's small solve does above): those of the test files by collecting the suite, those
# some tests import later (cvxpy, scipy, dask's distributed, trimesh and its networkx) by
# importing them; where PYTHONDONTWRITEBYTECODE is set, every worker and every process a
# test starts compiled them again (~10 s of CPU once; benchmarks/README.md, "make test CPU and wall")
$(TESTSTAMP): $(STAMP)
	@$(call install,-e '.[test]')
	@PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -q --collect-only -p no:xdist >/dev/null 2>&1 || true
	@PYTHONDONTWRITEBYTECODE= $(BIN)/python -c "import importlib, importlib.util as u; [importlib.import_module(m) for m in ('cvxpy', 'scipy.optimize', 'scipy.sparse.linalg', 'scipy.spatial', 'distributed', 'trimesh', 'networkx') if u.find_spec(m.split('.')[0])]" >/dev/null 2>&1 || true
	@touch $(TESTSTAMP)

# make docs: the [docs] extra (Sphinx, myst-parser, furo) on top of the runtime, never in it
$(DOCSTAMP): $(STAMP)
	@$(call install,-e '.[docs]')
	@touch $(DOCSTAMP)

# exit 1 from solve means "some design is not optimal": two examples are infeasible on purpose
# (tilt_spring_arm: springs cannot follow a tilting base; yasir2019_holder: the paper's design
# of the whole holder), and their reports say why; any other status stops make
# PYTHONDONTWRITEBYTECODE= : the demo's processes keep the .pyc of the libraries they import
# beyond the set-up's small solve (cvxpy, scipy, mujoco, yourdfpy, pandas...), in .venv
demo: $(STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/counterpoise solve problems/*.toml --out results --plot --jobs $(JOBS) || [ $$? -eq 1 ]

# the committed studies in results/: the Pareto front of the free-extensions leg, a
# 1000-point payload sweep of the hybrid (docs/studies.md), the tilting-base trade-off
# of the hybrid arm (docs/tilt.md) and the whole holder's residual against the leg planes'
# tilt (docs/seeds.md#yasir-holder)
studies: $(STAMP)
	$(BIN)/counterpoise study problems/yasir2019_free_extensions.toml --vary 'inertia_weight=0 1/m^2:400 1/m^2:41' --out results
	$(BIN)/counterpoise study problems/yasir2019_hybrid.toml --vary 'm_endo=400 g:1000 g:1000' --out results
	$(BIN)/python scripts/tilt_tradeoff.py results/tilt_hybrid_arm-tradeoff
	$(BIN)/counterpoise study problems/yasir2019_holder.toml --vary 'tilt=1 deg:15 deg:8' --out results

# the synthesis examples (problems/synthesis/, docs/synthesis.md) into results/<problem>-synthesis/
synthesis: $(STAMP)
	for f in problems/synthesis/*.toml; do PYTHONDONTWRITEBYTECODE= $(BIN)/counterpoise synthesise "$$f" --out results || exit 1; done

# type check first (docs/development.md: the settings are [tool.mypy] in pyproject.toml), then the suite
test: $(TESTSTAMP)
	$(BIN)/python -m mypy
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder

# the documentation site (docs/development.md#the-documentation-site): docs/*.md, problems/README.md,
# the generated command-line reference, API reference and gallery (from problems/ and results/),
# into docs/_build/html (git-ignored); any warning fails the build, after all are printed
docs: $(DOCSTAMP)
	$(BIN)/python -m sphinx -b html -W --keep-going -q docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_solve.py
	$(BIN)/python benchmarks/bench_scaling.py

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .hypothesis docs/_build docs/_generated docs/gallery
