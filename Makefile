# Two entry points on a fresh machine: `make demo` and `make test`. Each creates .venv itself.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-full install clean

# setup.py and the C++ source: the optional native extension is built by the install.
$(STAMP): pyproject.toml setup.py legsim/_native/pinlegsim.cpp
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/legsim run pronk --rrd out/pronk.rrd --html out/pronk.html --plot out/pronk.png

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

test-full: $(STAMP)
	LEGSIM_FULL=1 $(BIN)/python -m pytest -q -n 2

clean:
	rm -rf $(VENV) out .pytest_cache
