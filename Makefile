# The two commands a newcomer needs: `make demo` and `make test`.
# Both bootstrap first (idempotent: a few seconds when nothing changed).

SHELL := /bin/bash
ENV := scripts/env.sh
OUT ?= results/demo
PYTEST_ARGS ?=

.PHONY: bootstrap test test-fast demo lint clean toolchain

bootstrap:
	@bash scripts/bootstrap.sh

test: bootstrap
	$(ENV) python -m pytest $(PYTEST_ARGS)

test-fast: bootstrap
	$(ENV) python -m pytest -m "not slow and not e2e" $(PYTEST_ARGS)

demo: bootstrap
	$(ENV) python scripts/demo.py --out $(OUT)

# The PIC toolchain of firmware/ (sdcc pic14 built from Debian's source into a cache,
# gputils, gpsim, the PIC16F690 device files); without it the PIC and gpsim tests skip.
toolchain:
	@bash scripts/install_pic_toolchain.sh

lint: bootstrap
	$(ENV) ruff check .

clean:
	rm -rf ros2_ws/build ros2_ws/install ros2_ws/log ros2_ws/.bootstrap-ws ros2_ws/.bootstrap-interfaces
