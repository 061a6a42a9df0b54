# kflex — the two commands of the README, and their parts.
#   make run   set up, build (release) and run `kflex-cli run` on the shipped defaults
#   make test  set up, then every test (Rust workspace, Python)
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c

PYTHON ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
CARGO ?= cargo
RUN_ARGS ?=

.PHONY: run test venv fonts build test-rust test-embedded py-module test-python training-venv test-training smoke train lint fmt bench index-bench fit loops gallery clean

run: venv fonts build
	./target/release/kflex-cli run $(RUN_ARGS)

test: venv fonts test-rust test-embedded test-python test-training

# The figures' text (kflex-cli run --out) needs a TrueType font: Debian's
# fonts-dejavu-core, installed here where it is missing and we may (root with
# apt-get); KFLEX_FONT=FILE names another. Without one the runs warn and
# write no figures, and the figure tests fail.
DEJAVU := /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf
fonts:
	@if [ -z "$${KFLEX_FONT:-}" ] && [ ! -f $(DEJAVU) ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get install -y -q fonts-dejavu-core >/dev/null 2>&1 || { apt-get update -q >/dev/null && apt-get install -y -q fonts-dejavu-core; }; \
	  else \
	    echo "note: no font for the figures: apt-get install fonts-dejavu-core, or set KFLEX_FONT=FILE"; \
	  fi; \
	fi

venv: $(STAMP)

$(STAMP): requirements.txt
	@command -v $(CARGO) >/dev/null || { echo "cargo not found: install Rust from https://rustup.rs"; exit 1; }
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 10))' || { echo "$(PYTHON) must be Python >= 3.10"; exit 1; }
	$(PYTHON) -m venv $(VENV) || { echo "python venv failed: on Debian/Ubuntu, apt-get install python3-venv"; exit 1; }
	$(VPY) -m pip install --quiet --upgrade pip
	$(VPY) -m pip install --quiet -r requirements.txt
	touch $(STAMP)

build:
	$(CARGO) build --release --locked -p kflex-cli

# kflex-estimate's features are tested too: `onnx` (ONNX Runtime, KBJAE, the
# SCNN; its tests load the runtime library from .venv, which `make test`
# creates first) and `index` (the feature index; with `onnx`, IBJAE and LBHJAE);
# kflex-control's `estimators` (those estimators in the closed loop), `mcap` (logs)
# and `paper` (the paper's figures beside the grid's results).
RUST_TEST_FEATURES := --features kflex-estimate/onnx,kflex-estimate/index,kflex-control/estimators,kflex-control/mcap,kflex-control/paper
test-rust: venv
	$(CARGO) test --workspace --locked $(RUST_TEST_FEATURES)

# The crates a controller embeds, as it builds them: without default features
# (no rapier3d, parry3d or image; see ARCHITECTURE.md). `cargo test` builds
# their examples too, among them kflex-control's embedded_loop (estimator and
# compensator in a fixed-rate loop).
EMBEDDED := -p kflex-model -p kflex-estimate -p kflex-control
test-embedded:
	$(CARGO) test --locked $(EMBEDDED) --no-default-features

# the Python module kflex (crates/kflex-py) built by maturin and installed
# into .venv (editable: python/kflex links to the source); release profile,
# so the Python tests run at full speed
py-module: venv
	VIRTUAL_ENV=$(abspath $(VENV)) $(VENV)/bin/maturin develop --release --locked -q -m crates/kflex-py/Cargo.toml

test-python: venv py-module
	$(VPY) -m pytest -q tests/python

# The training environment (training/.venv, git-ignored): torch, onnx,
# onnxscript, onnxruntime (training/requirements.txt) for the scripts in
# training/ and their smoke tests; kept apart from .venv, so that the kflex
# package and `make run` never need torch. torch from PyPI comes with its
# CUDA libraries: about 5.5 GB on disk, about a minute to install on the
# development machine. The kflex module is the one `make py-module` builds
# into .venv (editable): a .pth file points the training environment at
# crates/kflex-py/python.
TVENV := training/.venv
TVPY := $(TVENV)/bin/python
TSTAMP := $(TVENV)/.installed

training-venv: $(TSTAMP)

$(TSTAMP): training/requirements.txt
	$(PYTHON) -m venv $(TVENV) || { echo "python venv failed: on Debian/Ubuntu, apt-get install python3-venv"; exit 1; }
	$(TVPY) -m pip install --quiet --upgrade pip
	$(TVPY) -m pip install --quiet -r training/requirements.txt
	echo "$(abspath crates/kflex-py/python)" > "$$($(TVPY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/kflex.pth"
	touch $(TSTAMP)

# the training scripts' smoke runs (a few steps each, ONNX against torch)
test-training: training-venv py-module
	$(TVPY) -m pytest -q training/tests

# both smoke runs, by hand: out/smoke/{kbjae,scnn}.onnx and their cards
smoke: training-venv py-module
	$(TVPY) training/train_kbjae.py --smoke --out out/smoke
	$(TVPY) training/train_scnn.py --smoke --out out/smoke

# the shipped models: trains KBJAE and the SCNN on freshly generated data and
# writes assets/models/{kbjae,scnn}.onnx with their model cards (on two
# cores about 6 and 25 minutes; a GPU is used where torch finds one)
train: training-venv py-module
	$(TVPY) training/train_kbjae.py
	$(TVPY) training/train_scnn.py

lint:
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets --locked -- -D warnings
	$(CARGO) clippy --workspace --all-targets --locked $(RUST_TEST_FEATURES) -- -D warnings
	$(CARGO) clippy $(EMBEDDED) --all-targets --locked --no-default-features -- -D warnings

fmt:
	$(CARGO) fmt --all

bench:
	$(CARGO) bench -p kflex-model -p kflex-estimate --features kflex-estimate/index
	python3 tools/bench_table.py

# the feature index against a linear scan, scipy's cKDTree and faiss's
# IndexFlatL2 on the same data (its own venv, tools/.venv-bench): synthetic
# embeddings, or with DB=dir SCNN=file a trained database's bands queried
# with fresh frames' embeddings (needs `make venv` for kflex)
index-bench:
	$(PYTHON) tools/index_bench.py $(if $(DB),--database $(DB) --scnn $(SCNN))

fit:
	$(CARGO) run --release --locked -p kflex-control --example fit_calibration

# the picture of the calibrated loops in crates/kflex-model/CALIBRATION.md
loops: venv
	$(VPY) tools/plot_loops.py

# the contact sheet of the clinical backgrounds (crates/kflex-model/examples/gallery.rs)
gallery:
	mkdir -p assets
	$(CARGO) run --release --locked -p kflex-model --example gallery -- assets/gallery.png

clean:
	rm -rf target $(VENV) $(TVENV)
