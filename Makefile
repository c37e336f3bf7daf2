# Set-up and the two everyday commands. Needs only python3 (>= 3.11) and pip:
# uv is installed on first use and then manages the environment from uv.lock.
UV := python3 -m uv
export UV_COMPILE_BYTECODE := 1
export PREFECT_SERVER_ANALYTICS_ENABLED := false

.PHONY: demo test lint bootstrap

bootstrap:
	@python3 -m uv --version >/dev/null 2>&1 || python3 -m pip install --quiet --disable-pip-version-check uv
	@$(UV) sync --locked --quiet

demo: bootstrap
	$(UV) run --locked ropeload demo

test: bootstrap
	$(UV) run --locked pytest

lint: bootstrap
	$(UV) run --locked ruff check .
	$(UV) run --locked ruff format --check .
