# The two commands that matter: `make run` brings the whole system up, `make test` runs the test suite.
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-$(shell sha1sum pyproject.toml | cut -c1-12)

.PHONY: run test install database lint bench

$(STAMP): pyproject.toml
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	rm -f $(VENV)/.installed-* && touch $@

install: $(STAMP)

# The development machine's own secret key (git-ignored), made once: the settings refuse the built-in one.
.fleet/secret-key:
	mkdir -p .fleet
	umask 077 && python3 -c 'import secrets; print(secrets.token_urlsafe(50))' > $@

database: install .fleet/secret-key
	$(PY) deploy/ensure_database.py
	$(PY) manage.py migrate --noinput

run: database
	$(PY) manage.py collectstatic --noinput --verbosity 0
	$(PY) manage.py api_token dev
	$(VENV)/bin/honcho start -f deploy/Procfile

test: install
	$(VENV)/bin/ruff check .
	DJANGO_SETTINGS_MODULE=fleet.test_settings $(PY) deploy/ensure_database.py
	$(PY) -m pytest $(PYTEST_ARGS)

lint: install
	$(VENV)/bin/ruff check .

# The benchmark: its own stack, the runs of bench/suite.py, bench/latest.md and .png (BENCH_SUITE=quick for a smoke
# run); then the worker layouts: step capacity with one and with two step-worker processes (one bridge).
bench: install
	$(PY) -m bench.suite --suite $(or $(BENCH_SUITE),full)
	rm -rf bench/results/layouts
	$(PY) -m bench.suite --suite scale --workers 1 --output bench/results/layouts
	$(PY) -m bench.suite --suite scale --workers 2 --output bench/results/layouts

# Fault injection, the long run: a private stack (own PostgreSQL, Redis, Mosquitto), random faults from a seed
# (FLEET_FAULT_SEED, else random; printed), checks afterwards (tests/faults). FAULTS_ARGS adds options.
.PHONY: faults
faults: install
	$(PY) -m tests.faults --robots 20 --missions 300 --fault-seconds 180 --quiet-seconds 300 $(FAULTS_ARGS)
