"""Golden outputs: the bytes of a few fixed runs, so a refactor or a speed-up is proven not to change them.

``python tests/golden.py --update`` rewrites ``tests/data/golden.json`` from the current code;
do that only when an output is meant to change, and say why in the commit.  The digests hold on
one platform's numpy/scipy/libm; a different BLAS or CPU may need a regeneration.
"""
from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

GOLDEN = Path(__file__).parent / "data" / "golden.json"
FILES = ("channels.csv", "events.csv", "motion.bvh", "face_arkit.csv")
REAL = "ovos/female-407676__nagwense__comical-evil-laugh"  # 11 s, 48 kHz, test split

#: name -> command-line overrides (every run: seed 0).  The papers' pipelines pin ``detector=none``
#: (their bytes are the papers'); ``default`` is the default run, the yamnet detector on.
RUNS = {
    "default": ["input.duration_s=12"],
    "papers_default": ["input.duration_s=12", "detector=none"],
    "hill_facs": ["input.duration_s=8", "extractor=pressure", "body=hill", "face=facs", "scheduler=none",
                  "detector=none"],
    "phoneme_cgm_concat_fourier": ["input.duration_s=8", "extractor=phoneme", "face=cgm",
                                   "scheduler=concat", "body=fourier", "detector=none"],
    "follow_detector": ["input.duration_s=8", "body=follow", "face=facs", "detector=laugh"],
    "real_48k": ["input=file", "face=facs", "detector=none"],
    "real_48k_yamnet": ["input=file", "face=facs"],
}


def real_path() -> str:
    from laughlab.corpora import fetch

    return str(fetch.require(kinds=["laugh"])[REAL])


def run(name: str, out: Path) -> dict[str, str]:
    """Run one golden combination into ``out``; the sha256 of each of its output files."""
    args = list(RUNS[name])
    if "input=file" in args:
        args.append(f"input.path={real_path()}")
    proc = subprocess.run([sys.executable, "-m", "laughlab", f"hydra.run.dir={out}", "seed=0", *args],
                          capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"golden run {name} failed: {proc.stderr.strip()}")
    return {f: hashlib.sha256((out / f).read_bytes()).hexdigest() for f in FILES if (out / f).exists()}


def main() -> None:
    import tempfile

    if "--update" not in sys.argv:
        sys.exit("usage: python tests/golden.py --update   (rewrites tests/data/golden.json)")
    with tempfile.TemporaryDirectory() as tmp:
        digests = {name: run(name, Path(tmp) / name) for name in RUNS}
    GOLDEN.write_text(json.dumps(digests, indent=1, sort_keys=True) + "\n")
    print(f"wrote {GOLDEN}")


if __name__ == "__main__":
    main()
