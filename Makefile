# usvfast developer targets. `make help` lists them.
.DEFAULT_GOAL := help
SHELL := /bin/bash
VENV := .venv
export VIRTUAL_ENV := $(abspath $(VENV))
export PATH := $(VIRTUAL_ENV)/bin:$(PATH)
# Extras installed for development and CI (the peers we prove parity against; the SSD's
# OpenVINO back-end and its int8 quantisation, tested against OpenCV DNN).
EXTRAS ?= test,openvino,quantize

.PHONY: help dev torch lint fmt test test-rust test-python demo bench wheel

help: ## List the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk 'BEGIN {FS = ":.*## "} {printf "  %-12s %s\n", $$1, $$2}'

$(VENV)/bin/maturin:
	python3 -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q "maturin>=1.7,<2"

dev: $(VENV)/bin/maturin ## Create .venv, build the Rust extension (release) and install it with its extras
	maturin develop --release --extras $(EXTRAS)
	# TrackEval (HOTA oracle of the tests) requires opencv-python, which would shadow
	# opencv-python-headless: install it without its dependencies (numpy and scipy are here).
	pip install -q --no-deps "trackeval>=1.3"
	# OpenCV 5 keeps CascadeClassifier and STAR in the contrib build: install it over the
	# headless wheel at the same version (a superset) for the cascade-XML test.
	pip install -q --no-deps --force-reinstall "opencv-contrib-python-headless==$$(python -c \
		'import importlib.metadata as m; print(m.version("opencv-python-headless"))')"

torch: dev ## Install the CPU-usable torch for the YOLO tests and benches (the `yolo` extra)
	bash .ci/install-torch.sh $(VENV)/bin/python

lint: dev torch ## cargo fmt/clippy, ruff check/format, pyright (static types of python/usvfast; it reads torch)
	cargo fmt --check
	cargo clippy --all-targets -- -D warnings
	cargo clippy --all-targets --features python -- -D warnings
	ruff check python tests benches
	ruff format --check python tests benches
	pyright --pythonpath $(VIRTUAL_ENV)/bin/python

fmt: dev ## Format Rust and Python sources
	cargo fmt
	ruff format python tests benches
	ruff check --fix python tests benches

test-rust: ## Rust unit tests (no Python linked)
	cargo test

test-python: dev torch ## Python tests (parity with peers, real data, bad input)
	python -m pytest -q

test: lint test-rust test-python ## Everything CI runs: lint, Rust tests, Python tests

demo: $(VENV)/bin/maturin ## Main job: the bundled harbour recording through the whole pipeline (installs only what it needs)
	maturin develop --release --extras demo
	usvfast demo --out out/demo

bench: dev torch ## Criterion benches and Python comparisons against the peers
	cargo bench
	python benches/run.py

wheel: $(VENV)/bin/maturin ## manylinux2014 x86_64 wheel (maturin + zig) into dist/, checked by auditwheel; and an sdist
	$(VENV)/bin/pip install -q ziglang auditwheel
	maturin build --release --zig --compatibility manylinux2014 --out dist
	auditwheel show dist/usvfast-*manylinux2014*.whl
	maturin sdist --out dist
