"""What a wheel of laughlab carries (a packaging review, 2026-11-29): the licences of everything it bundles in its
metadata, and lower bounds under which its commands run."""
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]


def source_copy(tmp_path) -> Path:
    """The checkout's files (tracked, and new ones not ignored) in a folder of their own: a build writes build/ and
    *.egg-info where it runs, and a build/ left in the checkout would ship a module since deleted (the diff review)."""
    src = tmp_path / "src"
    if not (ROOT / ".git").exists():   # an unpacked sdist: its own files, without what a build leaves
        shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__", ".venv*",
                                                                 "dist"))
        return src
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, capture_output=True,
                           check=True).stdout.decode().split("\0")
    for name in filter(None, files):
        if (ROOT / name).is_file():
            (src / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, src / name)
    return src


def test_the_wheel_declares_and_carries_every_bundled_licence(tmp_path):
    """The wheel said ``License-Expression: MIT`` though it bundles YAMNet (Apache-2.0) and three.js and three-vrm
    (MIT), whose licence files sat among the package data where scanners do not look."""
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w",
                        str(tmp_path / "dist"), str(source_copy(tmp_path))], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    (wheel,) = (tmp_path / "dist").glob("laughlab-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        meta = z.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode("utf-8")
    assert "License-Expression: MIT AND Apache-2.0" in meta.splitlines()
    files = set(re.findall(r"^License-File: (.+)$", meta, re.M))
    assert {"LICENSE", "laughlab/data/yamnet/LICENSE", "laughlab/data/yamnet/NOTICE"} <= files
    assert {f"laughlab/viewer/vendor/{v}/LICENSE" for v in ("three", "three_vrm", "three_vrm_animation")} <= files
    assert "laughlab/data/yamnet/NOTICE" in names and "laughlab/data/yamnet/yamnet.tflite" in names
    assert not [n for n in names if n.startswith(("tests/", "runs/", "multirun/")) or "__pycache__" in n]


def test_the_scipy_lower_bound_has_what_the_harness_calls():
    """The experiments' confidence intervals call ``scipy.stats.bootstrap(rng=...)``, which scipy has since 1.15;
    ``scipy>=1.11`` let pip install 1.11-1.14, under which every experiment stopped after its last trial with a
    TypeError (the packaging review installed each lower bound)."""
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["dependencies"]
    (scipy,) = [d for d in deps if re.match(r"scipy\b", d)]
    assert Version(re.search(r">=\s*([\d.]+)", scipy)[1]) >= Version("1.15")
    assert "rng=" in (ROOT / "laughlab/harness/results.py").read_text(encoding="utf-8")   # still what it calls


def test_the_sdist_holds_what_its_tests_need(tmp_path):
    """The sdist held the 90 test modules without conftest.py, tests/data (the golden outputs), tests/assets, the
    docs the README links or the lock the tests run from (MANIFEST.in now grafts them)."""
    import tarfile

    dist = tmp_path / "dist"
    src = source_copy(tmp_path)
    (src / "benchmarks" / "results").mkdir(exist_ok=True)   # a machine's own measurements (git ignores them)
    (src / "benchmarks" / "results" / "latency.json").write_text("{}", encoding="utf-8")
    r = subprocess.run([sys.executable, "-c", f"from setuptools import build_meta; build_meta.build_sdist({str(dist)!r})"],
                       cwd=src, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    (sdist,) = dist.glob("laughlab-*.tar.gz")
    with tarfile.open(sdist) as t:
        names = {n.split("/", 1)[1] for n in t.getnames() if "/" in n}
    assert {"tests/conftest.py", "tests/golden.py", "tests/inprocess.py", "tests/data/golden.json", "requirements.lock",
            "constraints.txt", "Makefile", "CITATION.cff", "docs/pipeline.md", "laughlab/data/yamnet/NOTICE",
            "benchmarks/bench_latency.py"} <= names   # tests load the latency benchmark's replay
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc") or n.startswith("benchmarks/results")]
