# Two entry points: `make demo` and `make test`. Both set everything up from a fresh clone.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
SYSTEM_PACKAGES := libode8 libosmesa6 libegl1 libegl-mesa0 libgl1-mesa-dri gcc libc6-dev
EXTRAS ?= dev,rl,server,llm,ray,recorded,sysid

.PHONY: demo test lint typecheck bench system-deps venv clean

system-deps:
	@bash scripts/system-deps.sh $(SYSTEM_PACKAGES)

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[$(EXTRAS)]"
	touch $@

venv: system-deps $(VENV)/.installed

lint: venv
	$(VENV)/bin/ruff check src tests bench examples
	$(VENV)/bin/lint-imports

typecheck: venv
	$(VENV)/bin/mypy

test: venv lint typecheck
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(VENV)/bin/pytest -n 2 -q tests

demo: venv
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(VENV)/bin/dualtwin demo --out runs/demo

bench: venv
	$(PY) bench/run_all.py

clean:
	rm -rf $(VENV) runs .pytest_cache .mypy_cache .ruff_cache
