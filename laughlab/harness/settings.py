"""The experiment settings every experiment shares (``harness.*``), checked before anything runs.

A wrong type given on the command line (``harness.jobs=two``, ``harness.corpus.profiles=mild``,
``harness.plots=maybe``) is one line naming the key, what it takes and what it got, before any trial and
before anything is written.  Keys an experiment adds for itself (``harness.fit``, ``harness.presets``,
...) are its own module's to check.
"""
from __future__ import annotations

import math
from numbers import Real

from laughlab.core.errors import LaughlabError


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, Real) and not isinstance(v, bool)


def _fail(key: str, takes: str, got) -> None:
    raise LaughlabError(f"harness.{key} must be {takes} (got {got!r})")


def _check(spec: dict, key: str, ok, takes: str, prefix: str = "") -> None:
    if key in spec and not ok(spec[key]):
        _fail(prefix + key, takes, spec[key])


def _section(spec: dict, key: str, prefix: str, takes: str) -> dict | None:
    """``spec[key]``, a mapping of settings, or None when it is absent or null."""
    v = spec.get(key)
    if v is not None and not isinstance(v, dict):
        _fail(prefix + key, takes, v)
    return v


def _str_or_none(v) -> bool:
    return v is None or isinstance(v, str)


def _list_of(test):
    return lambda v: isinstance(v, list) and all(test(x) for x in v)


def _seeds(v) -> bool:
    """A list of seeds, each once: a seed twice ran its trials twice into one folder (a new-user review: the
    second stopped on the first's files, or with one job both counted in the means as two trials)."""
    return _list_of(_seed)(v) and len(set(v)) == len(v)


def _seed(v) -> bool:
    """A seed: a whole number >= 0 (a review: a negative one passed this check and failed in the first trial)."""
    return _is_int(v) and v >= 0


def _seconds(v) -> bool:
    return _is_number(v) and 0 < v < math.inf


#: (key, test, what it takes) of ``harness.corpus`` and of ``harness.corpus.real``
CORPUS = (("profiles", _list_of(lambda p: isinstance(p, str)), "a list of synthetic profiles, e.g. [mild, intense]"),
          ("seeds", lambda v: _seed(v) or _seeds(v), "a number of seeds or a list of different seeds, each >= 0"),
          ("duration_s", _seconds, "a finite duration in seconds, above 0"),
          ("folder", _str_or_none, "a folder of recordings or null"),
          ("on_bad", lambda v: v in ("stop", "skip"), "stop or skip"))
REAL = (("sets", _list_of(lambda s: isinstance(s, str)), "a list of sets, e.g. [real, mixed]"),
        ("split", lambda v: v in ("train", "test", "all"), "train, test or all"),
        ("scenes", lambda v: _is_int(v) and v >= 0, "a whole number of scenes"),
        ("duration_s", _seconds, "a finite duration in seconds, above 0"),
        ("snr_db", _list_of(_is_number), "a list of signal-to-noise ratios in dB, e.g. [20, 10]"),
        ("seed", _seed, "a whole number >= 0"),
        ("if_missing", lambda v: v in ("stop", "skip"), "stop or skip"))


#: the shared top-level settings (an experiment's own keys come from its config and its module)
SHARED = ("name", "module", "conditions", "run_seeds", "showcase", "jobs", "keep_trials", "plots", "corpus")


def _unknown(spec: dict, known, prefix: str, near_only: bool = False) -> None:
    """Refuse a key of ``spec`` that is not one of ``known`` (a review: ``+harness.corpus.seed=1,2`` ran two identical
    points); with ``near_only``, only a key close to a known one (an experiment adds keys of its own at the top)."""
    import difflib

    for key in spec:
        if key in known:
            continue
        near = difflib.get_close_matches(str(key), known, n=1, cutoff=0.75)
        if near or not near_only:
            hint = f"; did you mean harness.{prefix}{near[0]}?" if near else ""
            where = f"harness.{prefix}".rstrip(".")
            raise LaughlabError(f"unknown parameter harness.{prefix}{key}: {where} takes {', '.join(known)}{hint}")


def check_harness(h: dict, added=None) -> None:
    """Raise one ``LaughlabError`` line for the first shared ``harness`` setting of the wrong type or range
    (``h``: the resolved ``harness`` section as plain containers).  ``added``: the top-level keys the command line
    added with ``+harness.KEY``; only those are checked for a near-miss of a shared name (an experiment's YAML may
    add keys of its own, ``plot`` or ``condition`` among them: a diff review); None checks every key."""
    if not isinstance(h, dict):
        raise LaughlabError(f"harness must be a mapping of settings (got {h!r})")
    _check(h, "name", _str_or_none, "a name")
    _check(h, "module", _str_or_none, "a module name or null")
    _check(h, "conditions", lambda c: c is None or (isinstance(c, dict) and all(
        v is None or _list_of(lambda o: isinstance(o, str))(v) for v in c.values())),
        "a mapping of condition name to a list of overrides, e.g. {energy: [scheduler=energy]}")
    _check(h, "run_seeds", _seeds, "a list of different whole numbers >= 0, e.g. [0, 1]")
    _check(h, "showcase", _str_or_none, "an input's id (e.g. mixed-s00) or null")
    _check(h, "jobs", lambda v: _is_int(v) and v >= 1, "a whole number of parallel trial processes, at least 1")
    for flag in ("keep_trials", "plots"):
        _check(h, flag, lambda v: isinstance(v, bool), "true or false")
    _unknown(h if added is None else {k: v for k, v in h.items() if k in added}, SHARED, "", near_only=True)
    corpus = _section(h, "corpus", "", "a mapping (profiles, seeds, duration_s, folder, on_bad, real)")
    if corpus is None:
        return
    _unknown(corpus, [k for k, _, _ in CORPUS] + ["real"], "corpus.")
    if isinstance(corpus.get("real"), dict):
        _unknown(corpus["real"], [k for k, _, _ in REAL], "corpus.real.")
    for key, ok, takes in CORPUS:
        _check(corpus, key, ok, takes, "corpus.")
    real = _section(corpus, "real", "corpus.", "a mapping (sets, split, scenes, duration_s, snr_db, seed, if_missing)")
    for key, ok, takes in REAL if real is not None else ():
        _check(real, key, ok, takes, "corpus.real.")
