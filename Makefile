# Two commands for a newcomer: `make demo` and `make test` (both set up the venv first).
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin

.PHONY: setup demo test bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	$(BIN)/python -m gnppdsl.geometry.native
	# bytecode of the sources: a process that must compile them (PYTHONDONTWRITEBYTECODE, an
	# editable install never imported) spends ~0.5 s CPU on it at every start (bench_komo.py)
	$(BIN)/python -m compileall -q gnppdsl
	touch $@

demo: setup
	$(BIN)/gnpp solve examples/planar/p3_occupied.pntc --json out/demo.json
	$(BIN)/gnpp view out/demo.json --html out/demo.html --force
	@echo
	@echo "Next steps:"
	@echo "  open out/demo.html in a browser      the plan in 3-D: play, step through the actions, the conflict learned"
	@echo "  . $(VENV)/bin/activate                 puts gnpp on your path (gnpp --help)"
	@echo "  gnpp solve examples/lab/lab1.pntc --view   two Panda arms, opened in the viewer"
	@echo "  docs/tutorial.md                     write and solve your own problem, view and export it"
	@echo "  docs/api.md                          the same from Python or Jupyter"
	@echo "  make test                            the test suite"

test: setup
	$(BIN)/python -m pytest $(PYTEST_ARGS)

bench: setup
	$(BIN)/gnpp bench examples/planar

clean:
	rm -rf $(VENV) build dist *.egg-info
