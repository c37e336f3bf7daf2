# Set-up and the two everyday commands. Needs only python3 (>= 3.11) and pip:
# uv is installed on first use and then manages the environment from uv.lock.
UV := python3 -m uv
export UV_COMPILE_BYTECODE := 1
export PREFECT_SERVER_ANALYTICS_ENABLED := false

.PHONY: demo test lint bootstrap browser

bootstrap:
	@python3 -m uv --version >/dev/null 2>&1 || python3 -m pip install --quiet --disable-pip-version-check uv
	@$(UV) sync --locked --quiet

demo: bootstrap
	$(UV) run --locked ropeload demo

# The HTML report's test in a real browser wants Chromium: Debian's, installed here when
# none is on PATH and apt-get can (as root, CI's case); elsewhere that one test skips.
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	 command -v google-chrome >/dev/null 2>&1 || \
	 { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
	   echo "make: installing Debian's chromium for the report's browser test" && \
	   apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium \
	     >/dev/null 2>&1; } || true

test: bootstrap browser
	$(UV) run --locked pytest

lint: bootstrap
	$(UV) run --locked ruff check .
	$(UV) run --locked ruff format --check .
