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

.PHONY: demo test test-5.0 test-4.2 test-warp bench extension validate clean venvs system-deps

venvs: $(VENV)/.installed $(VENV42)/.installed

# bpy needs X11 client libraries and Mesa's EGL/llvmpipe (software OpenGL) to load and draw.
SYSTEM_LIBS := libX11.so.6 libXrender.so.1 libXfixes.so.3 libXi.so.6 libxkbcommon.so.0 libEGL.so.1 libSM.so.6 libGL.so.1
system-deps:
	@missing=$$(for l in $(SYSTEM_LIBS); do ldconfig -p | grep -q "$$l" || echo $$l; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing system libraries for bpy (missing: $$missing)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libsm6 libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri >/dev/null; \
	fi

$(VENV)/.installed: requirements/blender-5.0.txt requirements/common.txt | system-deps
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements/blender-5.0.txt
	touch $@

$(VENV42)/.installed: requirements/blender-4.2.txt requirements/common.txt | system-deps
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

# One BLAS thread: the warp core's arrays are tiny, and idle BLAS threads only spin against other work.
bench: $(VENV)/.installed
	OPENBLAS_NUM_THREADS=1 $(PY) -m bench.warp_speed

# The installable extension zip, built with the CLI that ships inside the bpy wheel.
BLENDER_EXT = $(wildcard $(VENV)/lib/python3.11/site-packages/bpy/*/scripts/addons_core/bl_pkg/cli/blender_ext.py)
extension: $(VENV)/.installed
	mkdir -p dist
	$(PY) $(BLENDER_EXT) build --source-dir . --output-dir dist

validate: $(VENV)/.installed
	$(PY) $(BLENDER_EXT) validate .

clean:
	rm -rf dist out .cache .pytest_cache .hypothesis
