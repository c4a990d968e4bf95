# Two commands on a fresh machine: `make demo` and `make test`. Each creates .venv when
# missing and installs the project into it (again whenever pyproject.toml or the lock changes).
# Installs are reproducible: every package is pinned by constraints.txt (the exact versions the
# suite passed with); pyproject.toml keeps lower bounds. `make lock` refreshes the pins on purpose.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
LOCK   := constraints.txt
PIP_INSTALL = $(BIN)/python -m pip install --quiet --disable-pip-version-check -c $(LOCK)
PYTEST_ARGS ?=
# The suite runs on every core (at most 4: each worker loads the robots and builds its solvers),
# tests handed out by pytest-xdist with work stealing so the long ones do not queue behind each
# other. PYTEST_WORKERS=0 runs it in one process.
PYTEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 2); [ "$$n" -gt 4 ] && n=4; echo $$n)
PYTEST_XDIST = $(if $(filter 0,$(PYTEST_WORKERS)),,-n $(PYTEST_WORKERS) --dist worksteal)

.PHONY: demo test lint install lock bench bench-quick clean

$(STAMP): pyproject.toml $(LOCK)
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	@echo "installing wbmp and its dependencies into $(VENV) from $(LOCK) (first time: a few minutes)"
	@$(PIP_INSTALL) pip > $(VENV)/pip.log 2>&1 || { cat $(VENV)/pip.log; echo "install of pip from $(LOCK) failed"; exit 1; }
	@$(PIP_INSTALL) -e '.[test]' > $(VENV)/pip.log 2>&1 || { cat $(VENV)/pip.log; echo "install from $(LOCK) failed"; exit 1; }
	@grep -v "^WARNING: Location" $(VENV)/pip.log || true
	@rm -f $(VENV)/pip.log
	@$(BIN)/python -c "import wbmp, pinocchio, casadi, proxsuite, mujoco, meshcat" || (echo "install failed"; exit 1)
	@$(MAKE) --no-print-directory bytecode
	@touch $(STAMP)

# The project's bytecode, compiled once here as pip compiles an installed package's: a process
# with PYTHONDONTWRITEBYTECODE=1 set (or a read-only checkout) otherwise compiles ~250 modules on
# every run (~0.5 s of CPU; docs/performance.md). A module edited later is compiled again by
# Python on its next import when it may write, else by `make bytecode`.
.PHONY: bytecode
bytecode:
	@$(BIN)/python -m compileall -q language tasks robots planner sim viz wbmp > /dev/null

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/wbmp demo

# Lint and type gate (configured in pyproject.toml): ruff over the tree, mypy over the packages
# (its cache in .mypy_cache/). Both must be clean; `make test` runs them first.
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

test: $(STAMP) lint
	$(BIN)/python -m pytest $(PYTEST_XDIST) $(PYTEST_ARGS)

# The suite plus the tests marked long (minutes each).
.PHONY: test-long
test-long: $(STAMP) lint
	WBMP_LONG_TESTS=1 $(BIN)/python -m pytest $(PYTEST_XDIST) $(PYTEST_ARGS)

bench: $(STAMP)
	$(BIN)/wbmp bench

bench-quick: $(STAMP)
	$(BIN)/wbmp bench --quick

# The keyframe strip of every action on talos, for docs/primitives.md and the README.
.PHONY: pictures
pictures: $(STAMP)
	$(BIN)/python examples/action_pictures.py

# Peers (Crocoddyl, TSID) in their own environments .venv-crocoddyl and .venv-tsid (never .venv):
# the first run compiles TSID from source (long); results go to benchmarks/results/peers/.
.PHONY: bench-peers
bench-peers: $(STAMP)
	bash benchmarks/peers/setup.sh || echo "some peer environments are unavailable; continuing with the others"
	$(PYTHON) benchmarks/peers/run_peers.py
	$(BIN)/wbmp bench --quick --peers

# Refresh the lock on purpose (new releases, a changed lower bound): a fresh venv outside the
# tree resolves pyproject.toml's bounds to the newest versions, and its exact set (without pip's
# build tools and without wbmp itself) replaces $(LOCK). Run it with Python 3.11 on x86_64 Linux
# (the CI's kind), then `make test` reinstalls from the new lock; commit the lock once it passes.
lock:
	@d=$$(mktemp -d) && trap 'rm -rf "$$d"' EXIT && \
	$(PYTHON) -m venv "$$d/venv" && \
	{ "$$d/venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade pip && \
	  "$$d/venv/bin/python" -m pip install --quiet --disable-pip-version-check -e '.[test]'; \
	} > "$$d/pip.log" 2>&1 || { cat "$$d/pip.log"; echo "make lock: the install failed; $(LOCK) is unchanged"; exit 1; } && \
	where=$$("$$d/venv/bin/python" -c 'import platform as p; print("Python", p.python_version(), p.machine(), p.system())') && \
	{ echo "# Exact versions that \`make\` installs (pip install -c $(LOCK)), resolved by \`make lock\`"; \
	  echo "# on $$where from pyproject.toml's lower bounds. Refresh on purpose with"; \
	  echo "# \`make lock\`, then \`make test\`; commit the new pins once the suite passes."; \
	  "$$d/venv/bin/python" -m pip freeze --all --exclude-editable | grep -vE '^(setuptools|wheel)=='; \
	} > "$$d/lock" && mv "$$d/lock" $(LOCK) && \
	echo "$(LOCK): $$(grep -c '==' $(LOCK)) pins ($$where); now run make test"

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
