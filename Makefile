# Two commands on a fresh machine: `make demo` and `make test`. Each creates .venv when
# missing and installs the project into it (again whenever pyproject.toml changes).
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
PYTEST_ARGS ?=

.PHONY: demo test install bench bench-quick clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	@echo "installing wbmp and its dependencies into $(VENV) (first time: a few minutes)"
	@$(BIN)/python -m pip install --quiet --disable-pip-version-check --upgrade pip 2>&1 | grep -v "^WARNING: Location" || true
	@$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test]' 2>&1 | grep -v "^WARNING: Location" || true
	@$(BIN)/python -c "import wbmp, pinocchio, casadi, proxsuite, mujoco, meshcat" || (echo "install failed"; exit 1)
	@touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/wbmp demo

test: $(STAMP)
	$(BIN)/python -m pytest $(PYTEST_ARGS)

bench: $(STAMP)
	$(BIN)/wbmp bench

bench-quick: $(STAMP)
	$(BIN)/wbmp bench --quick

# Peers (Crocoddyl, TSID) in their own environments .venv-crocoddyl and .venv-tsid (never .venv):
# the first run compiles TSID from source (long); results go to benchmarks/results/peers/.
.PHONY: bench-peers
bench-peers: $(STAMP)
	bash benchmarks/peers/setup.sh || echo "some peer environments are unavailable; continuing with the others"
	$(PYTHON) benchmarks/peers/run_peers.py
	$(BIN)/wbmp bench --quick --peers

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
