# Set-up and checks of BSP Triangulate. `make demo` and `make test` install whatever is missing:
# QGIS from Debian's packages, then a venv on /usr/bin/python3 with the pinned dev packages.
#
#   make demo       set up, then run scripts/demo.py
#   make test       set up, then the whole suite on this machine's QGIS (3.22 on Debian 12),
#                   on QGIS 3.40 and on QGIS 3.44 (two Debian 13 chroots, each built once and
#                   cached), plus ruff
#   make test-host  the suite on this machine's QGIS only, plus ruff (fast, for development)
#   make test-340   the suite on QGIS 3.40 (Debian 13) in its chroot only
#   make test-344   the suite on QGIS 3.44 (Debian 13 + trixie-backports) in its chroot only
#   make package    dist/bsptriangulate-<version>.zip for the QGIS plugin manager
#   make bench      benchmarks against earcut, GEOS and QGIS (minutes)
#   make fuzz       the property tests with many more examples (minutes)
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
PYTEST_ARGS ?=
SUDO := $(shell [ "$$(id -u)" -eq 0 ] || echo sudo)
# Debian 12's qgis_process wrapper is broken; its qgis_process.bin works. Tests pick the same.
QGIS_PROCESS := $(shell command -v qgis_process.bin || command -v qgis_process)
APT_PACKAGES := python3-qgis qgis python3-venv

export QT_QPA_PLATFORM := offscreen

.PHONY: demo test test-host test-340 test-344 pytest lint qgis venv package bench fuzz clean

demo: venv
	$(PY) scripts/demo.py

# The three suites are independent: run them side by side (each chroot has its own folder and
# lock, so the first run builds both at once), each one's output printed whole when it ends.
test: qgis
	$(MAKE) -j3 --output-sync=target test-host test-340 test-344

test-host: pytest lint

# Each in its chroot, with a venv of its own inside it.
test-340 test-344: test-%: | qgis
	scripts/chroot_qgis.sh $* make VENV=/opt/bsptriangulate-venv pytest PYTEST_ARGS="$(PYTEST_ARGS)"

# pytest's exit code 5 (no test collected) fails here too, as any non-zero code does. Bash's
# `time` reports the suite's wall and CPU time (its worker processes and qgis_process runs
# included): three suites share this machine's cores, so their CPU time sets `make test`'s.
pytest: venv
	@$(PY) -c 'import qgis.core, sys; print("QGIS", qgis.core.Qgis.version(), "Python", sys.version.split()[0])'
	TIMEFORMAT='pytest: %0R s wall, %0U s user, %0S s sys'; time $(PY) -m pytest -q $(PYTEST_ARGS)

lint: venv
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

# QGIS from Debian when its Python bindings are missing; python3-venv, without which Debian's
# python3 makes venvs without pip.
qgis:
	@/usr/bin/python3 -c 'import qgis.core' 2>/dev/null || { \
		echo "Installing QGIS from Debian's packages"; \
		$(SUDO) apt-get update -qq && \
		$(SUDO) env DEBIAN_FRONTEND=noninteractive \
			apt-get install -y -qq --no-install-recommends $(APT_PACKAGES); }
	@dpkg -s python3-venv >/dev/null 2>&1 || { \
		$(SUDO) apt-get update -qq && \
		$(SUDO) env DEBIAN_FRONTEND=noninteractive \
			apt-get install -y -qq --no-install-recommends python3-venv; }

venv: $(VENV)/.done
$(VENV)/.done: requirements-dev.txt | qgis
	/usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q -r requirements-dev.txt
	touch $@

package:
	/usr/bin/python3 scripts/package.py

bench: venv
	$(PY) bench/run_all.py

# Property tests with many more examples (minutes; not part of `make test`).
fuzz: venv
	HYPOTHESIS_PROFILE=fuzz $(PY) -m pytest -q tests/core/test_properties.py

clean:
	rm -rf dist build .pytest_cache .ruff_cache .hypothesis
