# Two entry points on a fresh machine: `make demo` and `make test`. Each creates .venv itself.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-full test-browser install lint lint-tools clean wheel

DEPS_STAMP := $(VENV)/.dependencies-installed

# The environment legsim installs into: pip, the build requirements and legsim's dependencies
# (its test extra included), all read from pyproject.toml. `make lint` needs only this, so CI
# runs the checkers while the install builds the native extension (.ci/run).
$(DEPS_STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	@# The build requirements go into the venv and legsim builds there, without isolation: an
	@# isolated build would install Pinocchio's 400 MB of headers and libraries into a throwaway
	@# environment, besides the same libpinocchio that the `pin` dependency brings.
	$(BIN)/python -c 'import tomllib; t = tomllib.load(open("pyproject.toml", "rb")); print(*t["build-system"]["requires"], *t["project"]["dependencies"], *t["project"]["optional-dependencies"]["test"], sep="\n")' > $(VENV)/requirements.txt
	$(BIN)/pip install --quiet -r $(VENV)/requirements.txt
	touch $(DEPS_STAMP)

# setup.py and the C++ source: the optional native extension is built by the install.
$(STAMP): $(DEPS_STAMP) setup.py robots/_native/pinlegsim.cpp
	$(BIN)/pip install --quiet --no-build-isolation --no-deps -e .
	@$(BIN)/python -c "import legsim.robots._native as n; print('legsim: native robot library:', n.status())"
	@# The step loop and the bundled models compiled ahead of time (about two minutes, once), so
	@# that a first run loads them instead of compiling.
	$(BIN)/python -m legsim.prebuild
	touch $(STAMP)

install: $(STAMP)

# A wheel that ships the prebuilt compiled code of this checkout's sources (legsim/_prebuilt,
# made anew first), so that a first run after `pip install` loads instead of compiling.
wheel: $(STAMP)
	$(BIN)/python -m legsim.prebuild
	$(BIN)/python -m build --wheel --outdir dist .

demo: $(STAMP)
	mkdir -p out
	$(BIN)/legsim run pronk --rrd out/pronk.rrd --html out/pronk.html --plot out/pronk.png
	@echo "to look at them: $(BIN)/rerun out/pronk.rrd (the Rerun viewer); out/pronk.html in a browser; out/pronk.png"

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

test-full: $(STAMP)
	LEGSIM_FULL=1 $(BIN)/python -m pytest -q -n 2

# The lint extra (exact ruff, mypy and stub versions) on top of the install, with its own stamp.
LINT_STAMP := $(VENV)/.lint-installed
# mypy checks the package under its installed names: a tree of links where robots/ and viz/ sit
# inside legsim/ as setup.py installs them ([tool.mypy] in pyproject.toml).
TYPECHECK_TREE := build/typecheck/legsim

# Only the extra's own requirements, on the dependencies: the checkers read the sources, not the
# installed package, so they need neither the native extension nor the prebuilt code.
$(LINT_STAMP): $(DEPS_STAMP) pyproject.toml
	$(BIN)/python -c 'import tomllib; print(*tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["lint"], sep="\n")' > $(VENV)/lint-requirements.txt
	$(BIN)/pip install --quiet -r $(VENV)/lint-requirements.txt
	touch $(LINT_STAMP)

lint-tools: $(LINT_STAMP)

# Both checkers run even when the first finds something, so one run lists every finding.
lint: $(LINT_STAMP)
	rm -rf $(TYPECHECK_TREE) && mkdir -p $(TYPECHECK_TREE)
	for entry in legsim/*; do ln -s "$(CURDIR)/$$entry" $(TYPECHECK_TREE)/; done
	ln -s "$(CURDIR)/robots" "$(CURDIR)/viz" $(TYPECHECK_TREE)/
	@status=0; \
	echo "$(BIN)/ruff check"; $(BIN)/ruff check || status=1; \
	echo "$(BIN)/ruff format --check"; $(BIN)/ruff format --check || status=1; \
	echo "$(BIN)/mypy"; $(BIN)/mypy || status=1; \
	exit $$status

# The only target that changes the machine: it installs Chromium with apt-get (as root, or
# through sudo) when no Chromium is on PATH, then runs the browser tests. `make test` never
# installs anything; without a browser it reports these tests as skipped.
BROWSERS := chromium chromium-browser google-chrome google-chrome-stable
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

test-browser: $(STAMP)
	@found=""; for b in $(BROWSERS); do command -v $$b >/dev/null 2>&1 && found=$$b && break; done; \
	if [ -z "$$found" ]; then \
	  echo "test-browser: no Chromium on PATH; installing the package chromium with apt-get (this changes the system)"; \
	  $(SUDO) apt-get update && $(SUDO) apt-get install -y chromium || exit 1; \
	fi
	$(BIN)/python -m pytest -q -p no:xdist -m browser tests/viz/test_browser_html.py

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache build/typecheck
