# The two commands of the README. Each creates .venv on first use and installs the
# project with every extra the main job and the tests need.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: compare test install clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[all,test]'
	touch $@

install: $(VENV)/.installed

compare: $(VENV)/.installed
	$(BIN)/swiptopt compare

test: $(VENV)/.installed
	$(BIN)/python -m pytest -n 2 -q

clean:
	rm -rf $(VENV) build *.egg-info
