# Lixel: two commands do everything on a fresh Linux machine with Python 3.11.
#   make demo   the main job (the speed-against-error report)
#   make test   the test suite under Blender 5.0 and Blender 4.2 LTS (bpy modules)
PYTHON ?= python3.11
VENV   := .venv
VENV42 := .venv-4.2
PY     := $(VENV)/bin/python
PY42   := $(VENV42)/bin/python
# Keep Blender's and Mesa's caches and user resources out of $HOME.
export XDG_CACHE_HOME ?= $(CURDIR)/.cache/xdg
export BLENDER_USER_RESOURCES ?= $(CURDIR)/.cache/blender-user

.PHONY: demo test test-5.0 test-4.2 test-warp bench extension validate clean venvs

venvs: $(VENV)/.installed $(VENV42)/.installed

$(VENV)/.installed: requirements/blender-5.0.txt requirements/common.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements/blender-5.0.txt
	touch $@

$(VENV42)/.installed: requirements/blender-4.2.txt requirements/common.txt
	$(PYTHON) -m venv $(VENV42)
	$(PY42) -m pip install --quiet --upgrade pip
	$(PY42) -m pip install --quiet -r requirements/blender-4.2.txt
	touch $@

demo: $(VENV)/.installed
	$(PY) -m bench.report $(if $(QUICK),--quick,) $(ARGS)

test: test-5.0 test-4.2

test-5.0: $(VENV)/.installed
	$(PY) -m pytest -q $(PYTEST_ARGS)

test-4.2: $(VENV42)/.installed
	$(PY42) -m pytest -q $(PYTEST_ARGS)

test-warp: $(VENV)/.installed
	$(PY) -m pytest -q tests/warp $(PYTEST_ARGS)

bench: $(VENV)/.installed
	$(PY) -m bench.warp_speed

# The installable extension zip, built with the CLI that ships inside the bpy wheel.
BLENDER_EXT = $(wildcard $(VENV)/lib/python3.11/site-packages/bpy/*/scripts/addons_core/bl_pkg/cli/blender_ext.py)
extension: $(VENV)/.installed
	mkdir -p dist
	$(PY) $(BLENDER_EXT) build --source-dir . --output-dir dist

validate: $(VENV)/.installed
	$(PY) $(BLENDER_EXT) validate .

clean:
	rm -rf dist out .cache .pytest_cache .hypothesis
