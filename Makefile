# Set-up and checks of BSP Triangulate. `make test` and `make demo` install what is missing.
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: test test-host lint venv

venv: $(VENV)/.done
$(VENV)/.done: requirements-dev.txt
	/usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q -r requirements-dev.txt
	touch $@

lint: venv
	$(PY) -m ruff check .

test-host: venv
	QT_QPA_PLATFORM=offscreen $(PY) -m pytest -q

test: test-host lint
