# rapid-cosim: one target per experiment; every target sets up what it needs from nothing.
PYTHON  ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
PY      := $(BIN)/python
RC      := $(BIN)/rapid-cosim
STAMP   := $(VENV)/.installed
SEED    ?= 1
N_JOBS  ?= 2
RESULTS ?= results
ARCHIVE ?=
MVA     ?=

# The repository's fmus/ is a developer's view of the FMUs an installed rapid-cosim builds
# into the user's cache: every target here builds into and reads from it.
export RAPID_COSIM_FMUS ?= $(CURDIR)/fmus

STAGED_TESTS := $(addprefix test,1 2 3 4 5 6 7 8 9 10)
TABLE1_TESTS := $(addprefix experiments/test,1 2 3 4 5 6 7 8)
RUN_OPTS     := --results $(RESULTS) --seed $(SEED) --n-jobs $(N_JOBS)
T0           := $(shell date +%s)
comma        := ,

.DEFAULT_GOAL := help
.PHONY: help install fmus demo test test-slow test-faults bench bench-diagnose bench-structures bench-electrical bench-timebase bench-fleet bench-replay bench-identify profile-identify records-diff stories-diff fleet clean table1 figures rerun event1 joint diagnose structures identify identify-electrical identify-steam identify-deadband identify-gas identify-png fleet-png bench-speed bench-delay bench-advice report-example event-electrical $(STAGED_TESTS)

help:  ## list the targets
	@grep -E '^[a-zA-Z0-9_%$$()-]+:.*## ' $(MAKEFILE_LIST) | sed 's/^$$(STAGED_TESTS)/test1..test10/' \
		| awk -F':.*## ' '{printf "  make %-20s %s\n", $$1, $$2}'

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -c constraints.txt -e '.[test]'
	touch $(STAMP)

install: $(STAMP)  ## create .venv and install rapid-cosim with pinned dependencies

fmus: $(STAMP)  ## compile the iGrGen test benches into fmus/ (only what changed)
	$(RC) build

demo: fmus  ## set up, then calibrate staged test 1 with PSO10+NM and PF10+NM; prints its figure and table
	$(RC) demo $(RUN_OPTS)

test: fmus  ## run the test suite (statistical suites at reduced size)
	$(PY) -m pytest -q -rs

test-slow: fmus  ## the statistical suites at full size (minutes; CI runs them after make test)
	$(PY) -m pytest -q -rs -m slow

test-faults: fmus  ## the interrupt tests (Ctrl-C, SIGTERM mid-run) RUNS=50 times in a row: how many pass
	@mkdir -p $(RESULTS); pass=0; for i in $$(seq $(or $(RUNS),50)); do \
		if $(PY) -m pytest -q -p no:cacheprovider tests/test_faults.py -k "interrupt" >$(RESULTS)/test-faults.log 2>&1; \
		then pass=$$((pass + 1)); else echo "run $$i failed:"; tail -n 30 $(RESULTS)/test-faults.log; fi; \
	done; echo "interrupt tests: $$pass of $(or $(RUNS),50) runs passed"; test $$pass -eq $(or $(RUNS),50)

$(STAGED_TESTS): test%: fmus  ## PSO10+NM and PF10+NM on one staged test, archived in results/testN/, with its figure
	$(RC) staged-test experiments/test$* $(RUN_OPTS)

table1: fmus  ## Table 1 (tests 1-8, both chains) as Markdown + CSV; runs what is not archived yet
	$(RC) staged-test $(TABLE1_TESTS) $(RUN_OPTS) --quiet
	$(RC) table1 --results $(RESULTS) --tests 1-8
	@echo "make table1: $$(( $$(date +%s) - $(T0) )) s wall time (set-up included)"

figures: fmus  ## fit figures (Figs. 3-8), convergence and particle clouds of every archived staged test
	@ls $(RESULTS)/test*/pf10+nm.h5 >/dev/null 2>&1 || $(MAKE) --no-print-directory table1
	$(RC) figures --results $(RESULTS)

rerun: fmus  ## re-run ARCHIVE=results/test1/pf10+nm.h5 from the archive alone; fails unless identical
	@test -n "$(ARCHIVE)" || { echo "usage: make rerun ARCHIVE=results/test1/pf10+nm.h5"; exit 2; }
	$(RC) rerun $(ARCHIVE) --n-jobs $(N_JOBS)

event1: fmus  ## PSO10+NM and PF10+NM on the recorded under-frequency event (COMTRADE), with its figure
	$(RC) staged-test experiments/event1 $(RUN_OPTS)

event-electrical: fmus  ## ANDES grid events recorded as electrical power: one fit (H estimated), the bias table P_e vs as if P_m
	$(PY) benchmarks/electrical_study.py --show tgov1_on

joint: fmus  ## joint Bayesian fit of R and Ts over tests 1-8 and event1, and how consistent each one's estimate is
	$(RC) staged-test $(TABLE1_TESTS) experiments/event1 $(RUN_OPTS) --quiet
	$(RC) joint --tests 1-8,event1 $(RUN_OPTS)
	@echo "make joint: $$(( $$(date +%s) - $(T0) )) s wall time"

diagnose: fmus  ## identify's explanation part alone: name what TG Type I misses on tests 1-10 (4 and 8 held out), write it into iGrGen.Diagnosed
	$(RC) diagnose $(addprefix experiments/test,1 2 3 5 6 7 9 10 4 8) --holdout test4 --holdout test8 \
		--results $(RESULTS)/diagnose --json $(RESULTS)/diagnose/verdict.json --seed $(SEED) --n-jobs $(N_JOBS) \
		--package modelica/iGrGen
	@echo "make diagnose: $$(( $$(date +%s) - $(T0) )) s wall time"

identify: fmus  ## one identification of the field unit (experiments/unit.toml): explanation, records, .dyr (.dyd with MVA=...), report HTML+PDF
	$(RC) identify experiments/unit.toml --results $(RESULTS)/identify --seed $(SEED) --n-jobs $(N_JOBS) $(if $(MVA),--mva $(MVA))
	@echo "make identify: $$(( $$(date +%s) - $(T0) )) s wall time"

identify-electrical: fmus  ## one identification from two ANDES grid events recorded as electrical power (experiments/electrical/unit.toml)
	$(RC) identify experiments/electrical/unit.toml --results $(RESULTS)/identify-electrical --seed $(SEED) --n-jobs $(N_JOBS)
	@echo "make identify-electrical: $$(( $$(date +%s) - $(T0) )) s wall time"

identify-steam: fmus  ## one identification of a steam unit with a binding opening rate from three ANDES grid events (experiments/steam/unit.toml)
	$(RC) identify experiments/steam/unit.toml --results $(RESULTS)/identify-steam --seed $(SEED) --n-jobs $(N_JOBS)
	@echo "make identify-steam: $$(( $$(date +%s) - $(T0) )) s wall time"

identify-deadband: fmus  ## one identification of a steam unit with a 36 mHz deadband from ANDES grid events (experiments/deadband/unit.toml): a TGOV1D record
	$(RC) identify experiments/deadband/unit.toml --results $(RESULTS)/identify-deadband --seed $(SEED) --n-jobs $(N_JOBS)
	@echo "make identify-deadband: $$(( $$(date +%s) - $(T0) )) s wall time"

identify-gas: fmus  ## one identification of a gas turbine from three ANDES grid events (experiments/gas/unit.toml): a GAST record
	$(RC) identify experiments/gas/unit.toml --results $(RESULTS)/identify-gas --seed $(SEED) --n-jobs $(N_JOBS)
	@echo "make identify-gas: $$(( $$(date +%s) - $(T0) )) s wall time"

identify-png: fmus  ## the README's picture of make identify's report (docs/identify_report.png); runs make identify if needed
	@test -f $(RESULTS)/identify/report.html || $(MAKE) --no-print-directory identify
	$(PY) -c "from rapid_cosim.report.pdf import screenshot; \
		print('wrote', screenshot('$(RESULTS)/identify/report.html', 'docs/identify_report.png', width=1100, height=1300))"

STRUCTURES := $(addprefix experiments/structures/,TGTypeI.toml TGOV1.toml IEEEG1.toml GGOV1.toml HYGOV.toml)  # shipped: rapid_cosim/structures/standard

structures: fmus  ## identify's deliverable part alone: which structure (TG Type I and the four standard ones, IEEEG1's rates and the deadbands free where they win) fits tests 1-10 (4, 8 held out), the records, identifiability
	$(RC) structures $(addprefix experiments/test,1 2 3 5 6 7 9 10 4 8) --holdout test4 --holdout test8 \
		--structures $(subst $(eval) ,$(comma),$(STRUCTURES)) --results $(RESULTS)/structures --seed $(SEED) --n-jobs $(N_JOBS)
	@echo "make structures: $$(( $$(date +%s) - $(T0) )) s wall time"

report-example: fmus  ## the validation report (HTML, PDF) of a synthetic TGOV1 unit, two tests held out; its picture in docs/
	$(PY) docs/report_example.py --results $(RESULTS)/report-example --picture docs/validation_report.png

bench-structures: fmus  ## identify's structure choice on synthetic campaigns (SEEDS=10 per standard structure): named, deadbands kept where none is, exported .dyr's RMSE/noise; campaigns kept in results/bench-structures/work (records-diff plays them)
	rm -rf $(RESULTS)/bench-structures/work  # a kept campaign's archives would be resumed, not fitted again
	$(PY) benchmarks/structures_study.py --seeds $(or $(SEEDS),10) --n-jobs $(N_JOBS) --json $(RESULTS)/bench-structures/study.json \
		--keep $(RESULTS)/bench-structures/work

bench-diagnose: fmus  ## confusion matrix of the discrepancy workflow on synthetic campaigns (SEEDS=1-5); then the true model on 200 effect-free campaigns: adequacy p-values, false alarms, interval coverage
	$(PY) benchmarks/diagnose_study.py --seeds $(or $(SEEDS),1-5) --n-jobs $(N_JOBS) --calibration 200 \
		--json $(RESULTS)/bench-diagnose/calibration.json

bench-electrical: fmus  ## fourteen ANDES events, TGOV1, IEEEG1, TG Type I (generate.py --study, needs andes: the test extra): errors, structures and effects, P_e vs P_m; five more with a hidden valve rate; 100 noise draws per event; the true governor on 30 more per event (false alarms, interval coverage)
	$(PY) benchmarks/electrical_study.py --study $(RESULTS)/electrical --structures --draws 100 --calibration 30 \
		--json $(RESULTS)/electrical/study.json

fleet: fmus  ## one grid event, every unit: the five synthetic units of experiments/fleet (records on file checked, the failing ones identified) on 2 local workers; results/fleet/fleet.html
	$(RC) fleet experiments/fleet/fleet.toml --results $(RESULTS)/fleet --n-jobs $(N_JOBS); \
		status=$$?; echo "make fleet: $$(( $$(date +%s) - $(T0) )) s wall time (exit status $$status)"

fleet-png: fmus  ## the README's picture of make fleet's page (docs/fleet_report.png); runs make fleet if needed
	@test -f $(RESULTS)/fleet/fleet.html || $(MAKE) --no-print-directory fleet
	$(PY) -c "from rapid_cosim.report.pdf import screenshot; \
		print('wrote', screenshot('$(RESULTS)/fleet/fleet.html', 'docs/fleet_report.png', width=1500, height=560))"

bench-fleet: fmus  ## 100 synthetic units on 2 workers (a 1- and 2-worker timing on 10 first): wrong records flagged, right ones passed, new records within their bands; a mixed fleet of MIXED=20 (deadbands, GAST); then the 100 recorded from 10 s before the event, checked only
	$(PY) benchmarks/fleet_study.py --units $(or $(UNITS),100) --scaling 10 --mixed $(or $(MIXED),20) --work $(RESULTS)/bench-fleet

bench-replay: fmus  ## delivered records put back into ANDES in closed loop: the steam unit (regular, jittered, PMU-style stamps), the electrical unit, the deadband unit (events of two sizes, and of one), the gas unit, a synthetic fleet's TGOV1/IEEEG1 units (FLEET_UNITS=20): RMSE/noise and largest error beside the plant's own record
	$(PY) benchmarks/replay_study.py --work $(RESULTS)/bench-replay --fleet-units $(or $(FLEET_UNITS),20) \
		--json $(RESULTS)/bench-replay/study.json

profile-identify: fmus  ## where an identification spends its time, by stage and kind of work: the steam unit, the electrical unit, the field unit, a fleet unit
	$(PY) benchmarks/profile_identify.py --work $(RESULTS)/profile-identify --json $(RESULTS)/profile-identify/profile.json

bench-identify: fmus  ## identifications timed before (BEFORE=7176f80, the last round) and after in one run (per stage, simulations, answers side by side, records' behaviour apart in noise units), and 10 fleet units on 2 workers
	$(PY) benchmarks/identify_bench.py --before $(or $(BEFORE),7176f80) --work $(RESULTS)/bench-identify --json $(RESULTS)/bench-identify/study.json

records-diff: fmus  ## make bench-replay and bench-fleet (PARTS=replay,fleet; structures too) at BEFORE=cb03e04 and here, their records compared by what they do (responses in noise units), routes and verdicts
	$(PY) benchmarks/records_diff.py --rev $(or $(BEFORE),cb03e04) --work $(RESULTS)/records-diff --parts $(or $(PARTS),replay$(comma)fleet)

stories-diff: fmus  ## make demo, diagnose, identify and fleet under the code before the speed and house work (b2983af) and HEAD: printed stories and answer files compared, times and paths aside
	-$(PY) benchmarks/stories_diff.py --work $(RESULTS)/stories-diff

bench-timebase: fmus  ## the committed ANDES events with only their time base changed (jitter, dropped frames, repeats, a gap, STAT flags): verdicts, estimates in SE, variance ratios, simulation cost; the electrical unit on untidy stamps
	$(PY) benchmarks/timebase_study.py --work $(RESULTS)/bench-timebase --unit

bench-speed: fmus  ## where a diagnosis spends its time: field, four-test and event campaigns, before and after
	$(PY) benchmarks/speed.py

bench-delay: fmus  ## what the exact transport delay costs: a delayed recorded-frequency bench against one without, per set, both runners
	$(PY) benchmarks/delay_cost.py

bench-advice: fmus  ## does the advised next test settle an ambiguity as often as it says? first diagnosis, advised test recorded, second diagnosis
	$(PY) benchmarks/advice_study.py

bench: fmus  ## print the performance figures
	$(PY) benchmarks/run.py

clean:  ## remove build outputs (fmus, results); keeps .venv
	rm -rf fmus/*.fmu fmus/*.json fmus/.work results
