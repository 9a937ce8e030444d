"""Golden outputs: a few fixed runs, so a refactor or a speed-up is proven not to change them.

Two strengths of check, chosen by where the test runs:

- **exact bytes** in the environment the goldens were made in: every package pinned in
  ``requirements.lock`` installed at its locked version (what ``make test`` builds), on the Python
  minor version, OS and CPU architecture recorded in ``tests/data/golden.json``.  numpy, scipy, numba
  and libm round differently from release to release, so bytes only hold in the locked environment.
  Within it, numpy's and OpenBLAS's kernels are pinned to AVX2's (``laughlab/_kernels.py``), so the
  bytes hold on AVX2 and AVX-512 machines alike; YAMNet's interpreter (XNNPACK) has no such switch, so
  the runs through it (:data:`YAMNET_RUNS`) have their bytes recorded per CPU family
  (:func:`cpu_family`), and on a family with none recorded they are not checked, and the test says so.
- **values within a tolerance** anywhere else (a newer numpy, macOS, ARM): every number of every
  output file equal to the golden file's within ``RTOL``/``ATOL`` below, every word equal.

``python tests/golden.py --update`` rewrites ``tests/data/golden.json`` and the golden files
(``tests/data/golden/NAME/FILE.gz``) from the current code, in the locked environment only; do it
only when an output is meant to change, and say why in the commit.
"""
from __future__ import annotations

import gzip
import hashlib
import json
import platform
import re
import sys
from importlib import metadata
from pathlib import Path

from laughlab._kernels import cpu_family  # noqa: F401 (the family the YAMNet runs' bytes are recorded for)

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).parent / "data" / "golden.json"
GOLDEN_DIR = Path(__file__).parent / "data" / "golden"
LOCK = ROOT / "requirements.lock"
FILES = ("channels.csv", "events.csv", "motion.bvh", "face_arkit.csv")
REAL = "ovos/female-407676__nagwense__comical-evil-laugh"  # 11 s, 48 kHz, test split

#: outside the locked environment, numbers must agree to a relative 1e-6 or an absolute 1e-4
#: (channels are weights in [0, 1] and angles in degrees written with 4-6 decimals)
RTOL, ATOL = 1e-6, 1e-4

#: name -> command-line overrides (every run: seed 0).  The papers' pipelines pin ``detector=none`` (their
#: bytes are the papers', whatever the default detector); ``default`` is the default run (detector=yamnet),
#: ``default_none`` the same run with every sound driving the character, as in the papers
RUNS = {
    "default": ["input.duration_s=12"],
    "default_none": ["input.duration_s=12", "detector=none"],
    "hill_facs": ["input.duration_s=8", "extractor=pressure", "body=hill", "face=facs", "scheduler=none",
                  "detector=none"],
    "phoneme_cgm_concat_fourier": ["input.duration_s=8", "extractor=phoneme", "face=cgm",
                                   "scheduler=concat", "body=fourier", "detector=none"],
    "follow_detector": ["input.duration_s=8", "body=follow", "face=facs", "detector=laugh"],
    "real_48k": ["input=file", "face=facs", "detector=none"],
    "real_48k_yamnet": ["input=file", "face=facs", "detector=yamnet"],
}


#: the runs through YAMNet (the default detector): XNNPACK's kernels, chosen by CPU, decide their bytes
YAMNET_RUNS = tuple(n for n, a in RUNS.items() if not any(o.startswith("detector=") for o in a)
                    or "detector=yamnet" in a)
#: the CPU family the bundled YAMNet heads (laughlab/data/yamnet/head.json, fuse.json) were fitted on (refitted
#: 2026-11-27 with the monotone speech streams, on an AMD EPYC with AVX-512; first fitted 2026-11-25/26 on AVX2):
#: ``yamnet_fit --check`` reproduces their bytes there only
HEADS_FITTED_ON = "avx+avx2+avx512f+avx512skx+avx512vbmi+avx512vnni"


def real_path() -> str:
    from laughlab.corpora import fetch

    return str(fetch.require(kinds=["laugh"])[REAL])


def run(name: str, out: Path) -> dict[str, bytes]:
    """Run one golden combination into ``out``; the bytes of each of its output files."""
    args = list(RUNS[name])
    if "input=file" in args:
        args.append(f"input.path={real_path()}")
    # the figures are not golden (FILES): drawing them would only cost time.  In this process (tests/inprocess.py):
    # a sweep runs its jobs in one process too, so a run that left state behind for the next would show here
    from inprocess import laughlab

    proc = laughlab(f"hydra.run.dir={out}", "seed=0", "~output.plots", *args)
    if proc.returncode:
        raise RuntimeError(f"golden run {name} failed: {proc.stderr.strip()}")
    return {f: (out / f).read_bytes() for f in FILES if (out / f).exists()}


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# -- the environment ---------------------------------------------------------------------------------

def platform_tag() -> dict[str, str]:
    """What, besides the packages, decides the bytes: Python's minor version, the OS, the CPU."""
    return {"python": platform.python_version_tuple()[0] + "." + platform.python_version_tuple()[1],
            "system": platform.system(), "machine": platform.machine()}


def locked_pins(lock: Path = LOCK) -> dict[str, str]:
    """The lock's ``name==version`` pins that apply here (their environment markers evaluated)."""
    from packaging.markers import Marker

    pins = {}
    for line in lock.read_text().splitlines():
        m = re.match(r"^([A-Za-z0-9_.\-]+)==([^\s;\\]+)\s*(?:;\s*([^\\]+?))?\s*\\?$", line)
        if m and (m.group(3) is None or Marker(m.group(3)).evaluate()):
            pins[re.sub(r"[-_.]+", "-", m.group(1)).lower()] = m.group(2)
    return pins


def lock_mismatches(lock: Path = LOCK) -> list[str]:
    """Every locked package that is missing here or installed at another version, as ``name want (have)``."""
    out = []
    for name, want in sorted(locked_pins(lock).items()):
        try:
            have = metadata.version(name)
        except metadata.PackageNotFoundError:
            have = "missing"
        if have != want:
            out.append(f"{name} {want} ({have})")
    return out


def exact_environment() -> tuple[bool, str]:
    """Whether this is the environment the golden bytes hold in, and if not, why (one line)."""
    recorded = json.loads(GOLDEN.read_text())["environment"]
    why = [f"{k} {recorded[k]} ({v})" for k, v in platform_tag().items() if recorded.get(k) != v]
    off = lock_mismatches()
    if off:
        why.append(f"{len(off)} packages off the lock, e.g. " + ", ".join(off[:3]))
    return not why, "; ".join(why)


# -- comparing by value ------------------------------------------------------------------------------

_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)", re.I)


def value_differences(got: bytes, want: bytes, rtol: float = RTOL, atol: float = ATOL) -> str | None:
    """None when two text outputs differ only in numbers within the tolerance; else the first difference.

    Both files are cut into words and numbers (CSV cells, BVH tokens); the words must be equal, the
    numbers close: |a - b| <= atol + rtol * |b|, NaN equal to NaN.
    """
    import numpy as np

    g, w = got.decode(), want.decode()
    g_words, w_words = _NUMBER.split(g), _NUMBER.split(w)
    if g_words != w_words:
        first = next((i for i, (a, b) in enumerate(zip(g_words, w_words)) if a != b), None)
        if first is None:
            return f"{len(g_words)} text pieces where the golden file has {len(w_words)}"
        return f"text differs near {w_words[first][:40]!r}"
    a = np.array([float(x) for x in _NUMBER.findall(g)])
    b = np.array([float(x) for x in _NUMBER.findall(w)])
    bad = ~np.isclose(a, b, rtol=rtol, atol=atol, equal_nan=True)
    if bad.any():
        i = int(np.argmax(bad))
        return (f"{int(bad.sum())} of {len(b)} numbers beyond rtol {rtol:g}/atol {atol:g}, "
                f"the first {a[i]!r} vs {b[i]!r}, the largest difference {float(np.max(np.abs(a - b)[bad])):.3g}")
    return None


def expected_hashes(name: str) -> tuple[dict | None, str]:
    """The recorded digests of run ``name`` on this CPU, and a note; None for a YAMNet run on a CPU family
    with no bytes recorded (the note names the families that have them)."""
    doc = json.loads(GOLDEN.read_text())
    if name not in YAMNET_RUNS:
        return doc["runs"][name], "exact bytes (the locked environment)"
    family, recorded = cpu_family(), doc.get("yamnet_cpu", {})
    if family not in recorded:
        return None, (f"not checked: YAMNet's XNNPACK kernels round differently by CPU, and its bytes are "
                      f"recorded for {', '.join(sorted(recorded)) or 'no family'}, not this CPU's ({family}); "
                      "python tests/golden.py --update-cpu records them")
    return recorded[family][name], f"exact bytes (the locked environment, CPU family {family})"


def golden_file(name: str, file: str) -> bytes:
    return gzip.decompress((GOLDEN_DIR / name / f"{file}.gz").read_bytes())


USAGE = """usage: python tests/golden.py --update | --update-cpu
  --update      rewrite tests/data/golden.json and tests/data/golden/ from the current code (the YAMNet runs'
                bytes recorded for other CPU families are dropped: they would be stale)
  --update-cpu  add this CPU family's bytes of the YAMNet runs, once every other run matches its golden bytes"""


def main() -> None:
    import tempfile

    if not {"--update", "--update-cpu"} & set(sys.argv):
        sys.exit(USAGE)
    off = lock_mismatches()
    if off and "--force" not in sys.argv:
        sys.exit(f"golden.py: this environment is not the lock's ({len(off)} packages differ, e.g. "
                 f"{', '.join(off[:3])}): run `make test` first, or add --force")
    doc = json.loads(GOLDEN.read_text()) if GOLDEN.exists() else {}
    family = cpu_family()
    with tempfile.TemporaryDirectory() as tmp:
        if "--update-cpu" in sys.argv:
            got = {name: {f: sha256(data) for f, data in run(name, Path(tmp) / name).items()} for name in RUNS}
            off = [n for n in RUNS if n not in YAMNET_RUNS and got[n] != doc["runs"][n]]
            if off:
                sys.exit(f"golden.py: {', '.join(off)} differ from their golden bytes: the code changed; use --update")
            doc.setdefault("yamnet_cpu", {})[family] = {n: got[n] for n in YAMNET_RUNS}
            GOLDEN.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
            print(f"recorded the YAMNet runs' bytes for CPU family {family} in {GOLDEN}")
            return
        runs = {}
        for name in RUNS:
            files = run(name, Path(tmp) / name)
            runs[name] = {f: sha256(data) for f, data in files.items()}
            (GOLDEN_DIR / name).mkdir(parents=True, exist_ok=True)
            for f, data in files.items():  # mtime 0: the same output, the same .gz bytes
                (GOLDEN_DIR / name / f"{f}.gz").write_bytes(gzip.compress(data, compresslevel=9, mtime=0))
    dropped = sorted(set(doc.get("yamnet_cpu", {})) - {family})
    yamnet = {family: {n: runs[n] for n in YAMNET_RUNS}}
    note = {k: v for k, v in doc.items() if k == "yamnet_cpu_note"}   # kept: why only some families are recorded
    GOLDEN.write_text(json.dumps({"environment": {**platform_tag(), "cpu": family}, "runs": runs,
                                  "yamnet_cpu": yamnet, **note}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {GOLDEN} and {GOLDEN_DIR}" + (f"; dropped the YAMNet bytes of {', '.join(dropped)} (record them "
                                               "there with --update-cpu)" if dropped else ""))


if __name__ == "__main__":
    main()
