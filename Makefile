# pumpsim: set-up, kernels, demo, tests and benchmarks. Everything runs inside .venv.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo-pumpdown install codegen docs demo demo-design test test-all bench bench-design bench-diagnose bench-diagnose-independent bench-independent-gas bench-ripple bench-benchlog-diagnose bench-intervals clean

install: $(STAMP)
$(STAMP): pyproject.toml setup.py
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

# the documentation's tools (pyproject.toml's docs extra), on top of the runtime
DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): $(STAMP)
	$(BIN)/pip install --quiet -e '.[test,docs]'
	touch $(DOCS_STAMP)

codegen: install
	$(BIN)/python -m pumpsim.variants --simd examples/*.toml
	$(BIN)/python -m pumpsim.variants bench/independent/rigs/*.toml  # the independent cross-check's rigs

demo: codegen
	mkdir -p out
	$(BIN)/pumpsim simulate examples/test_rig.toml --out out/test_rig.csv --plot out/test_rig.png
	$(BIN)/pumpsim simulate examples/ellipse_4vanes.toml --out out/ellipse_4vanes.csv --plot out/ellipse_4vanes.png
	$(BIN)/pumpsim identify examples/test_rig.toml examples/data/test_rig_measurement.csv --params mu \
		--json out/test_rig_fit.json --report out/test_rig_fit.html
	$(BIN)/pumpsim diagnose examples/ellipse_4vanes.toml examples/data/ellipse_hidden_effects.csv \
		--json out/ellipse_diagnosis.json --report out/ellipse_diagnosis.html
	$(MAKE) --no-print-directory demo-pumpdown
	$(MAKE) --no-print-directory demo-design  # last step (issue 14): the design studies

# the EVP example: 4 L booster, 101.3 -> 30 kPa at 13.5 V (full model, fast path, figures)
demo-pumpdown: codegen
	mkdir -p out
	$(BIN)/pumpsim pumpdown examples/evp_booster.toml --out out/evp_pumpdown.csv --json out/evp_pumpdown.json \
		--plot out/evp_pumpdown.png --report out/evp_pumpdown.html

# design studies at reduced size (full size: drop --samples)
demo-design: codegen
	mkdir -p out
	rm -rf out/rig_tolerances out/ellipse_grid  # fresh results (a rerun into a folder resumes it)
	$(BIN)/pumpsim sweep examples/studies/test_rig_tolerances.toml --samples 1024 --out out/rig_tolerances \
		--csv out/rig_tolerances.csv --report out/rig_tolerances.html
	$(BIN)/pumpsim sensitivity examples/studies/test_rig_tolerances.toml --samples 128 \
		--json out/rig_sensitivity.json --report out/rig_sensitivity.html
	$(BIN)/pumpsim sweep examples/studies/ellipse_grid.toml --out out/ellipse_grid --report out/ellipse_grid.html
	$(BIN)/pumpsim optimize examples/studies/ellipse_optimize.toml --json out/ellipse_optimize.json \
		--report out/ellipse_optimize.html

# the documentation site: warnings are errors, the gallery's examples run (docs/_build/html/index.html)
docs: codegen $(DOCS_STAMP)
	$(BIN)/sphinx-build -W --keep-going -q -b html docs docs/_build/html

# on every core (pytest-xdist; a module's tests stay on one worker, so its shared fixtures run once)
XDIST := -n auto --dist loadscope

test: codegen
	$(BIN)/python -m pytest -q $(XDIST) --durations=25

test-all: codegen
	$(BIN)/python -m pytest -q $(XDIST) -m 'slow or not slow'

bench: codegen
	mkdir -p out
	$(BIN)/python bench/run.py --json out/bench.json
	$(BIN)/python bench/design.py --json out/bench.json
	$(BIN)/python bench/pumpdown.py --json out/bench.json

bench-design: codegen
	mkdir -p out
	$(BIN)/python bench/design.py --json out/bench.json

bench-diagnose: codegen
	mkdir -p out
	$(BIN)/python bench/diagnose_grid.py --grid $(or $(GRID),reduced) --json out/bench_diagnose.json

# mu from the current's vane-passing ripple over sample rates x noise x seeds (QUICK=1: 0.5 and 2 kHz, one seed)
bench-ripple: codegen
	mkdir -p out
	$(BIN)/python bench/ripple_rates.py $(if $(QUICK),--quick) --json out/bench_ripple.json

# bench-log diagnosis: library effects, clean logs and changes outside the library x 2 noise levels x 2 seeds,
# rates before and after the misspecification guard (QUICK=1: one seed at 0.5 % noise, ~13 diagnoses)
bench-benchlog-diagnose: codegen
	mkdir -p out
	$(BIN)/python bench/benchlog_diagnose_grid.py $(if $(QUICK),--quick) $(if $(JOBS),--jobs $(JOBS)) $(if $(ATMOSPHERE),--atmosphere-known) \
		--json out/bench_benchlog_diagnose.json

# diagnose on records from an independent implementation of the spec (bench/independent; QUICK=1: ~20 cases)
bench-diagnose-independent: codegen
	mkdir -p out
	$(BIN)/python bench/independent/run.py $(if $(QUICK),--quick) --json out/bench_independent.json

# pumpsim diagnose/identify on bench logs from an independent pump-down model with hidden changes
# (bench/independent_gas; the truth in out/independent_gas/manifest.json; QUICK=1: ~20 logs), then
# gas_diagnose_grid.py: the sensor rivals and two pump effects x 2 seeds (QUICK=1: 1), in-process
bench-independent-gas: codegen
	mkdir -p out
	nice -n 10 $(BIN)/python bench/independent_gas/run.py $(if $(QUICK),--quick)
	nice -n 10 $(BIN)/python bench/independent_gas/gas_diagnose_grid.py $(if $(QUICK),--seeds 1)

bench-intervals: codegen
	mkdir -p out
	nice -n 10 $(BIN)/python bench/interval_coverage.py $(if $(QUICK),--seeds 6)

clean:
	rm -rf generated/*/ out .pytest_cache docs/_build docs/auto_examples docs/reference/generated
