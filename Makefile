# Every target sets itself up: a virtual environment in .venv on first use.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
export OMP_NUM_THREADS ?= 1

# The committed reports live in benchmarks/results/<preset> (the docs' results pages and the
# README's table are generated from them); the bench-* targets below update them. `make bench`
# writes into gp-bench's own default, ./benchmark-results/quick (git-ignored), so a checkout
# stays clean; `make bench OUT=benchmarks/results/quick` updates the committed quick run.
OUT ?= benchmark-results/quick

.PHONY: docs bench bench-recommended bench-full bench-acceptance bench-linearized bench-rti bench-compute \
	bench-pendulum bench-robustness bench-data-efficiency bench-own-env test throughput clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# the CPU build of torch from this machine's disk; a bare `torch` would pull CUDA
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e ".[rl,dev,bench,docs,mujoco]"
	touch $@

bench: $(VENV)/.installed
	$(PY) -m benchmarks --preset quick --out $(OUT)

bench-recommended: $(VENV)/.installed  # the README's results table (~5 min on 2 cores)
	$(PY) -m benchmarks --preset recommended --workers 2 --out benchmarks/results/recommended
	$(PY) -m benchmarks.update_readme recommended

bench-full: $(VENV)/.installed  # every experiment (paper tables, Dubins, sample efficiency, compute, peers, acceptance)
	$(PY) -m benchmarks --preset full --workers 2 --out benchmarks/results/full

bench-acceptance: $(VENV)/.installed  # the paper's tables and the MPC acceptance runs, README tables
	$(PY) -m benchmarks --preset paper-tables --workers 2 --out benchmarks/results/paper-tables
	$(PY) -m benchmarks --preset mpc-acceptance --workers 2 --out benchmarks/results/mpc-acceptance

bench-linearized: $(VENV)/.installed  # the linearized SSGP-MPC's acceptance runs (~9 min on 2 cores)
	$(PY) -m benchmarks --preset linearized --workers 2 --out benchmarks/results/linearized

bench-rti: $(VENV)/.installed  # real-time iteration vs converged MPC, and the peers comparison
	$(PY) -m benchmarks --preset rti --workers 2 --out benchmarks/results/rti

bench-compute: $(VENV)/.installed  # per-step times; converged vs RTI step against nodes, horizon, r, samples
	$(PY) -m benchmarks --preset compute --workers 2 --out benchmarks/results/compute

bench-pendulum: $(VENV)/.installed  # the fourth system, added in one file (~4 min)
	$(PY) -m benchmarks --preset pendulum --workers 2 --out benchmarks/results/pendulum

bench-robustness: $(VENV)/.installed  # the online-learning envelope: ~3,200 episodes, many hours
	$(PY) -m benchmarks --preset robustness --workers 2 --out benchmarks/results/robustness

bench-data-efficiency: $(VENV)/.installed  # success and interaction before success vs data, PILCO's cart pole (~70 min on 2 cores)
	$(PY) -m benchmarks --preset data-efficiency --workers 2 --out benchmarks/results/data-efficiency

bench-own-env: $(VENV)/.installed  # outside simulators: Pendulum-v1, DMC's cart-pole in MuJoCo (~15 min on 2 cores)
	$(PY) -m benchmarks --preset own-env --workers 2 --out benchmarks/results/own-env
	$(PY) -m benchmarks.update_readme own-env

test: $(VENV)/.installed
	$(PY) -m ruff check .
	$(PY) -m pytest -q

docs: $(VENV)/.installed  # the documentation site, warnings as errors: docs/_build/html
	$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html

throughput: $(VENV)/.installed
	$(PY) benchmarks/studies/env_throughput.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
