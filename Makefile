# Two commands do all set-up on a fresh machine: `make eval` and `make test`.
# Each creates .venv and installs what is missing (Debian packages included).
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.ipbench-installed
SITE := build/site
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
LDCONFIG := $(shell command -v ldconfig || echo /sbin/ldconfig)
export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= egl

.PHONY: eval test docs install-check setup lint clean

# The benchmark with its defaults: both scenes, random vs GP-IPM, 30 seeds, one video per
# policy and scene; perception is trained on first use and cached in results/cache.
eval: $(STAMP)
	$(VENV)/bin/ipbench eval sorting --workers 2 --video --out results/sorting --cache results/cache

# ruff, the documentation (strict; its log is shown only when it fails: mkdocs' --quiet would
# hide the warnings that --strict turns into errors), then the tests.
test: $(STAMP)
	$(PY) -m ruff check .
	@echo "mkdocs build --strict --site-dir $(SITE)"
	@log=$$($(VENV)/bin/mkdocs build --strict --site-dir $(SITE) 2>&1) || { echo "$$log"; exit 1; }
	$(PY) -m pytest -q -n 2

# The documentation site, built into $(SITE) (git-ignored).
docs: $(STAMP)
	$(VENV)/bin/mkdocs build --strict --site-dir $(SITE)

# A plain `pip install` of the repository (no extras, not editable) into a fresh venv outside
# it, run from outside it: package data, registration, the command (see .ci/install-check;
# $(STAMP) brings the Debian packages that rendering needs).
install-check: $(STAMP)
	bash .ci/install-check

lint: $(STAMP)
	$(PY) -m ruff check . && $(PY) -m ruff format --check .

setup: $(STAMP)

# Debian packages: libusb-1.0-0 (open3d) and Mesa EGL (headless MuJoCo rendering).
# ffmpeg ships inside imageio-ffmpeg. torch (the extra "deep") is installed first, at the
# tested release: the pin `torch==2.13.0` also matches the CPU build 2.13.0+cpu where a package
# index or wheel folder offers it, and pip prefers that local version over the plain release;
# left to the extra's range, pip would take the newest torch and gigabytes of CUDA packages.
$(STAMP): pyproject.toml
	@need=""; \
	$(LDCONFIG) -p | grep -q 'libusb-1.0.so.0' || need="$$need libusb-1.0-0"; \
	$(LDCONFIG) -p | grep -q 'libEGL.so.1' || need="$$need libegl1"; \
	$(LDCONFIG) -p | grep -q 'libEGL_mesa.so.0' || need="$$need libegl-mesa0 libgl1-mesa-dri"; \
	$(LDCONFIG) -p | grep -q 'libGL.so.1' || need="$$need libgl1"; \
	if [ -n "$$need" ]; then \
	  echo "Installing Debian packages:$$need"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$need; \
	fi
	[ -x $(PY) ] || python3 -m venv $(VENV)
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[dev,ray,deep,docs]'
	touch $(STAMP)

clean:
	rm -rf $(VENV) results .pytest_cache build
