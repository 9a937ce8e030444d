"""How reports write numbers and metric names: shared by the experiment report and the sweep report."""
from __future__ import annotations

import math

from laughlab.core.errors import LaughlabError
from laughlab.render.savefig import new_figure

#: metrics shown first in tables and heatmaps
KEY_METRICS = ("intensity_r_clip", "intensity_r_kinetic", "onset_latency_median_s", "miss_rate",
               "silent_start_rate", "offset_tail_s", "cutoff_rate", "repetition_rate", "clip_entropy")


def fmt(v, digits=3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    v = v + 0.0  # -0.0 (an entropy of nothing) shows as 0
    return f"{v:.{digits}g}" if abs(v) < 1000 else f"{v:.0f}"


def arrow(hib) -> str:
    return {True: "↑", False: "↓"}.get(hib, "")


def heading(metric: str, info: dict) -> str:
    """A metric's name with its better direction, as in the tables' first column: ``miss_rate ↓``."""
    return f"{metric} {arrow(info['higher_is_better'])}".rstrip()


def better_label(higher_is_better, units: str = "") -> str:
    """A colour bar's or value axis' label saying which way is better, under the values' ``units`` if given."""
    way = {True: "↑ better (higher values)", False: "↑ better (lower values; scale reversed)"}.get(
        higher_is_better, "neither end is better")
    return f"{units}\n{way}" if units else way


#: a swept parameter's unit by the end of its name, the configs' naming convention (``min_inactive_s``)
PARAM_UNITS = (("_per_s", "1/s"), ("_ms", "ms"), ("_s", "s"), ("_hz", "Hz"), ("_db", "dB"), ("_deg", "deg"))


#: the mark of a mean at the edge of its metric's search range, and the note that explains it
EDGE = "‡"


def at_search_edge(info: dict, r: dict) -> bool:
    """Does the mean ``r`` of a bounded-search metric (``info['search']``, e.g. a best lag in [0, 2] s) sit at an
    end of the range, as it does when every trial's best was found there?"""
    lo_hi = info.get("search")
    m = r.get("mean") if r.get("n") else None
    return bool(lo_hi) and m is not None and math.isfinite(m) and any(abs(m - b) <= 1e-9 for b in lo_hi)


def edge_note(metrics: list[str], infos: dict) -> str:
    """The footnote for :data:`EDGE`: which metrics, their ranges, what it means."""
    ranges = ", ".join(f"`{m}` [{fmt(infos[m]['search'][0])}, {fmt(infos[m]['search'][1])}] {infos[m]['units']}"
                       for m in metrics)
    return (f"{EDGE} every trial's best was found at the edge of the search ({ranges}): the value that goes with it "
            "(the correlation at that lag) was measured at the edge, and the best may lie beyond it.")


def param_label(key: str) -> str:
    """An axis label for a swept parameter: its key and, when its name says it, its unit
    (``scheduler.decrease_per_s (1/s)``); a key without a unit suffix is shown as it is."""
    unit = next((u for end, u in PARAM_UNITS if key.lower().endswith(end)), None)
    return f"{key} ({unit})" if unit else key


def vector_link(name: str) -> str:
    """The README's line under a figure ``figures/NAME.png``: its PDF beside it."""
    pdf = name.rsplit(".", 1)[0] + ".pdf"
    return f"Vector version (PDF, for print): [{pdf}](figures/{pdf})"


def panel_grid(n: int, w: float, h: float, cols: int = 3):
    cols = max(1, min(cols, n))
    rows = max(1, math.ceil(n / cols))
    fig, axes = new_figure(rows, cols, figsize=(w * cols, h * rows), dpi=130, squeeze=False, layout="constrained")
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat[:n])


def check_panels(doc: dict, panels: list[str] | None) -> None:
    """``report --panels``: a name the experiment did not measure is refused in one line, naming its metrics."""
    refuse_unmeasured("--panels", doc["experiment"], panels, doc["metrics"])


def refuse_unmeasured(flag: str, who: str, asked: list[str] | None, metrics) -> None:
    """LaughlabError, one line, for the names in ``asked`` not among ``metrics``: each with the nearest metric
    when one is near (a typo: ``missrate``, did you mean ``miss_rate``), then every metric ``who`` measured."""
    import difflib

    unknown = [m for m in asked or [] if m not in metrics]
    if unknown:
        named = [m + "".join(f" (did you mean {near}?)" for near in difflib.get_close_matches(m, list(metrics), n=1))
                 for m in unknown]
        raise LaughlabError(f"{flag}: {who} measured no {', '.join(named)}; its metrics: " + ", ".join(metrics))


def played_no_clip(doc: dict, cond: str) -> bool:
    """True when no trial of ``cond`` played a clip (e.g. ``scheduler=none``): ``cutoff_rate``, a fraction
    of the played clips, has no value in any of its trials although other metrics have."""
    rs = doc["results"][cond]
    return "cutoff_rate" in rs and not rs["cutoff_rate"]["n"] and any(r["n"] for r in rs.values())


#: the metrics of a detector's own laughter signal: under ``detector=none`` (always "laughter") its recall is 1 and
#: its latency a frame, by construction, not a best (a new-user review: the report bolded them for ``none``)
DETECTOR_OWN = ("detector_f1", "detector_precision", "detector_recall", "detection_latency_median_s",
                "detection_latency_p90_s", "probability_latency_median_s", "probability_in_time")


def vacuous(doc: dict, metric: str, cond: str) -> bool:
    """A lower-is-better value of 0 under a condition that played no clip (an offset tail of no clip), or a
    detector's own metric under ``detector=none`` (:data:`DETECTOR_OWN`): not a best, so a report's best
    (``report._clear_best``) and a sweep's figures leave it out."""
    r = doc["results"][cond][metric]
    if metric in DETECTOR_OWN and "detector=none" in (doc.get("conditions") or {}).get(cond, ()):
        return True
    return doc["metrics"][metric]["higher_is_better"] is False and r["mean"] == 0 and played_no_clip(doc, cond)


#: a result with no value (a figure leaves its cell blank)
NO_VALUE = {"mean": None, "ci95": [None, None], "std": None, "n": 0}
