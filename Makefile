# fdir-service: `make demo` and `make test` set themselves up on first use.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
TEST_WORKERS ?= 2
STAMP  := $(VENV)/.installed
# numpy's AVX2 kernels on every machine, AVX-512 ones too: the same bits everywhere (docs/recording.md, "Same bits on other machines")
export NPY_DISABLE_CPU_FEATURES ?= X86_V4 AVX512_ICL AVX512_SPR

.PHONY: demo test lint bench clean venv

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m sim_bridge.demo $(DEMO)

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist worksteal

lint: $(STAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/sim-bridge bench
	$(BIN)/sim-bridge bench --filters
	$(BIN)/fdir bench
	$(BIN)/python benchmarks/service_latency.py
	$(BIN)/python benchmarks/replay_speed.py

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
