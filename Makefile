# The two commands of the README. Each creates .venv on first use and installs the
# project with every extra the main job and the tests need.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
MODEL_PACKAGES := torch|stable[-_]baselines3|sb3[-_]contrib|gymnasium

.PHONY: compare test install constraints clean

# constraints.txt pins every package a fresh clone installs (for Python 3.11, CI's; other
# Pythons resolve the rest freely), so that two machines run the same code: `make constraints`
# refreshes it from what pip resolves today in a scratch environment. The packages whose
# versions name a trained model (MODEL_PACKAGES; rl.deep.model_versions) are pinned for
# every Python, so that `swiptopt compare` finds the models shipped with swiptopt there too.
$(VENV)/.installed: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[all,test]'
	touch $@

constraints:
	rm -rf .venv-constraints
	$(PYTHON) -m venv .venv-constraints
	.venv-constraints/bin/python -m pip install --quiet --upgrade pip
	.venv-constraints/bin/python -m pip install --quiet -e '.[all,test]'
	{ echo '# Every package `make install` takes, pinned; refreshed by `make constraints`.'; \
	  .venv-constraints/bin/python -m pip freeze --exclude-editable \
	    | sed -E '/^($(MODEL_PACKAGES))==/!s/$$/ ; python_version == "3.11"/'; } > constraints.txt
	rm -rf .venv-constraints

install: $(VENV)/.installed

compare: $(VENV)/.installed
	$(BIN)/swiptopt compare

test: $(VENV)/.installed
	$(BIN)/python -m pytest -n 2 -q

clean:
	rm -rf $(VENV) .venv-constraints build *.egg-info
