# Every target that runs something depends on the virtual environment, so on a fresh
# machine `make match` or `make test` is the only command needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install train match test test-busy warm-up test-long bench bench-accuracy protocol browser lint clean

install: $(STAMP)

# Re-installs only when the project metadata changes; the packages are editable.
$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "pingpong needs python3 >= 3.11, found " + sys.version.split()[0])'
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

match: install
	$(BIN)/pingpong match

# The learning example's extra (examples/train_ppo.py): stable-baselines3 and torch (pyproject.toml).
TRAIN_STAMP := $(VENV)/.train-installed
train: $(TRAIN_STAMP)

$(TRAIN_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[train]'
	touch $(TRAIN_STAMP)

lint: install
	$(BIN)/lint-imports

# Two workers: CI has two cores and a cold run is mostly numba compiling, one specialisation
# per effect combination. The warm-up first compiles what the tests' worker processes run, so no
# test waits for a server that is still compiling; a test file stays on one worker (loadfile), so
# its own specialisations compile once and the other worker finds them in numba's on-disk cache.
test: lint browser train warm-up
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=25

warm-up: install
	$(BIN)/python -m tests.warmup

# The suite on a busy machine: `make test` beside two CPU hogs, stopped whatever its result.
test-busy: install
	$(BIN)/python -m tests.hogs 2 -- $(MAKE) test

# The web page's tests run in the system's headless Chromium: installed here as root where it is
# missing (CI); without root they are skipped, and say how to install.
browser:
	@if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
		apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends chromium chromium-driver; \
	else echo "no chromium: the browser tests will be skipped (apt-get install chromium chromium-driver)"; fi

test-long: install
	$(BIN)/python -m pytest -q -m long

# pytest exits 5 when bench/ holds no benchmark yet: that is not a failure of `make bench`.
bench: install bench-accuracy
	$(BIN)/python -m pytest bench --benchmark-enable -q || test $$? -eq 5

# The work-precision study: rewrites docs/accuracy.md's accuracy block and bench/accuracy.png (a few minutes).
bench-accuracy: install
	$(BIN)/python -m bench.accuracy --png bench/accuracy.png --readme docs/accuracy.md

# The protocol document's generated tables (layouts, enums, limits), from the wire's code.
protocol: install
	$(BIN)/python -m processes.network.wire.protocol docs/protocol.md

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks
