# Thin wrapper over the scripts (they are the source of truth; see README.md).
.PHONY: setup test lint run pc clean-build

setup:
	./scripts/setup.sh

test:
	./scripts/test-all.sh

lint:
	./scripts/lint.sh

run:
	./scripts/run-default.sh

# one session under process-compose, headless
pc: setup
	tools/bin/process-compose -f deploy/process-compose.yaml up -U -t=false

# removes the C++ build only (.venv and the caches outside the clone stay)
clean-build:
	rm -rf build/ik_cpp
