"""Make ``tests/data/papers_index.json``: the numbered equations, figures, tables and code listings of
the four source papers, with a short caption of each in our words.

    python tools/make_papers_index.py PAPERS_DIR [--out tests/data/papers_index.json]

PAPERS_DIR holds the papers as plain text (one ``.txt`` file each, extracted from the published PDFs;
they are not part of this repository).  Each paper's file is recognised by a phrase of its text, and
the numbers are read from it by the patterns below:

- van Duijn 2014: equations are the lines ``(3.1)``; figures the captions ``Figure 3.1:``; its code
  listings are unnumbered, so a listing is a section (``3.1.1``, ``5.2``, ...) whose text holds
  pseudo-code lines (``for every timestep:``, ``class``, ``def``, ``if ...:``, ``random.shuffle``).
- DiLorenzo et al. 2008: equations are lines ending in ``(1)``; figures the captions ``Figure 1:``.
  Its two tables (the Hill parameters and the activations) are unnumbered and are not indexed.
- Unuma et al. 1995: equations end in ``(1)`` or ``(6-1)``; figures are the captions ``Figure 1.`` and
  the references ``Fig. 3`` (Figure 3's caption is lost in the text).
- Ding et al. 2014: equations are the lines ``(1)``; figures ``Figure 1:``; tables ``Table 1:``.

The script refuses to write the index unless every number it finds has a caption below and every
caption a number it found, so the index is the papers' numbering, no more and no less.  The index was
made once with this script; ``tests/test_fidelity_doc.py`` reads only the index, never the papers.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

PAPERS = [
    {
        "key": "vanduijn2014",
        "heading": "van Duijn 2014",
        "citation": "van Duijn, Real-time laughter on virtual characters. MSc thesis, Utrecht University, 2014.",
        "phrase": "we directly drive synthesized breathing and",
        "equation": r"^\((\d\.\d)\)$",
        "figure": r"^Figure (\d\.\d):",
        "table": None,
        "captions": """
            equation 3.1: RMS amplitude of a chunk of samples
            equation 3.2: rise and fall limit of the motion control signal
            equation 3.3: chest influence = 1 - MCS
            equation 3.4: belly influence = MCS
            equation 4.1: laughing energy recurrence with clip consumption and three constraints
            figure 1.1: game characters laughing (prior art)
            figure 1.2: a game cutscene with a laughing child (prior art)
            figure 2.1: emotional states of a game (prior art)
            figure 2.2: frames of a crying animation (prior art)
            figure 2.3: techniques to animate a face
            figure 2.4: the system's architecture
            figure 3.1: MCS after a calibration peak, min/max fixed or drifting
            figure 3.2: MCS raw and with two rise/fall settings
            figure 3.3: a typical MCS, one peak per call
            figure 3.4: chest and belly breathing shapes
            figure 3.5: chest states, extrapolated
            figure 3.6: fake and genuine smiles
            figure 3.7: neutral and smiling face shapes
            figure 3.8: eyes open while pointing
            figure 4.1: sketch of the laughing energy process
            figure 4.2: regions of the laughing energy process
            figure 5.1: shape keys in action
            figure 5.2: an over-exaggerated face
            listing 3.1.1: mapping the amplitude to [0, 1] with min/max so far
            listing 3.2.2: smoothing by a queue of recent values
            listing 5.2: the live sound: amplitude to motion control signal
            listing 5.3: the Smoother class and its four instances
            listing 5.4: the laughing energy per time step
            listing 5.5: the Action class, the 11 actions and the selection loop
        """,
    },
    {
        "key": "dilorenzo2008",
        "heading": "DiLorenzo et al. 2008",
        "citation": "P. C. DiLorenzo, V. B. Zordan, B. L. Sanders, Laughing out loud: control for modeling anatomically "
                    "inspired laughter using audio. ACM Transactions on Graphics 27(5) (SIGGRAPH Asia), 2008.",
        "phrase": "hierarchical control method which synthesizes",
        "equation": r"\((\d)\)$",
        "figure": r"^Figure (\d+):",
        "table": None,
        "captions": """
            equation 1: lung pressure = pleural + transmural pressure
            equation 2: Boyle's law for the pleural pressure
            equation 3: lung volume updated by the flow
            equation 4: turbulent flow from the pressure difference
            figure 1: a rendered laugh and its audio against simulated pressure
            figure 2: the five torso components
            figure 3: Hill force-length and force-velocity multipliers
            figure 4: audio against tracheal pressure, and a prediction
            figure 5: linearised pressure/volume relationship
            figure 6: the chest wall cavity
            figure 7: error of one call: simulated annealing against simplex
            figure 8: a skinned deep belly laugh at 0.6 s intervals
            figure 9: skin against the torso simulation
            figure 10: generated against input pressure for a bout
        """,
    },
    {
        "key": "unuma1995",
        "heading": "Unuma et al. 1995",
        "citation": "M. Unuma, K. Anjyo, R. Takeuchi, Fourier principles for emotion-based human figure animation. "
                    "Proceedings of SIGGRAPH 95, ACM, 1995.",
        "phrase": "Fourier Principles for Emotion-based Human Figure Animation",
        "equation": r"\((\d(?:-\d)?)\)\$*$",
        "figure": r"(?:^Figure |Fig\. ?)(\d+)\b",
        "table": None,
        "captions": """
            equation 1: rescaled Fourier model of a joint angle
            equation 2: the same for a second motion
            equation 3: interpolation and extrapolation between two motions
            equation 4: hip height while walking
            equation 5: hip height while running
            equation 6-1: rescaled model of the first data set
            equation 6-2: rescaled model of the second data set
            equation 7-1: amplitude differences
            equation 7-2: phase differences
            equation 8: Fourier characteristic function
            figure 1: skeleton model
            figure 2: local coordinate system
            figure 3: walks blended from normal to tired
            figure 4: the step effect
            figure 5: definition of hip position
            figure 6: gait of feet
            figure 7: superposition of behaviours
            figure 8: demonstration editor
            figure 9: running examples with step constraints
            figure 10: stills from an animation
        """,
    },
    {
        "key": "ding2014",
        "heading": "Ding et al. 2014",
        "citation": "Y. Ding, K. Prepin, J. Huang, C. Pelachaud, T. Artières, Laughter animation synthesis. "
                    "Proceedings of AAMAS 2014.",
        "phrase": "contextual Gaussian Model",
        "equation": r"^\((\d)\)$",
        "figure": r"^Figure (\d+):",
        "table": r"^Table (\d+):",
        "captions": """
            equation 1: contextual Gaussian mean, linear in the context
            equation 2: Gaussian likelihood of the motion given the context
            equation 3: maximum-likelihood estimate of the model's matrix
            equation 4: total cost of a segment sequence
            equation 5: duration cost term of the total
            equation 6: continuity cost term of the total
            equation 7: duration cost function
            equation 8: continuity cost function
            figure 1: overall architecture
            figure 2: head and eyebrow synthesis framework
            figure 3: shape of the duration and continuity costs
            figure 4: PD controller for torso and shoulders
            figure 5: synthesized lips, front view
            figure 6: synthesized data, front view
            figure 7: synthesized data, side view
            figure 8: the experiment's interface
            table 1: post-hoc results per pair of conditions
        """,
    },
]

CODE = re.compile(r"^\s*(for (every|each) ?time-?step:|class \w+|def \w+\(|if .*:|random\.shuffle)")
SECTION = re.compile(r"^\d\.\d(\.\d)?$")


def listings(text: str) -> list[str]:
    """Sections whose text holds pseudo-code lines (the thesis' unnumbered listings)."""
    lines = text.splitlines()
    starts = [(i, line.strip()) for i, line in enumerate(lines) if SECTION.fullmatch(line.strip())]
    out = []
    for k, (i, number) in enumerate(starts):
        end = starts[k + 1][0] if k + 1 < len(starts) else len(lines)
        if any(CODE.match(line) for line in lines[i:end]):
            out.append(number)
    return out


def captions(paper: dict) -> dict[tuple[str, str], str]:
    """``kind number: caption`` lines -> {(kind, number): caption}."""
    out = {}
    for line in paper["captions"].strip().splitlines():
        head, caption = line.split(":", 1)
        kind, number = head.split()
        out[(kind, number)] = caption.strip()
    return out


def numbers(text: str, paper: dict) -> set[tuple[str, str]]:
    found = set()
    for kind in ("equation", "figure", "table"):
        if paper[kind]:
            found |= {(kind, m) for m in re.findall(paper[kind], text, re.M)}
    if paper["key"] == "vanduijn2014":
        found |= {("listing", n) for n in listings(text)}
    return found


def order(item: tuple[str, str]) -> tuple:
    kind, number = item
    return ("equation", "figure", "table", "listing").index(kind), [int(x) for x in re.split(r"[.-]", number)]


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("papers_dir")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "tests" / "data" / "papers_index.json"))
    ns = ap.parse_args(argv)
    texts = [p.read_text(errors="replace") for p in sorted(Path(ns.papers_dir).glob("*.txt"))]
    doc = {"made_by": "tools/make_papers_index.py", "papers": []}
    for paper in PAPERS:
        text = [t for t in texts if paper["phrase"] in t]
        if len(text) != 1:
            sys.exit(f"make_papers_index: error: {len(text)} texts hold {paper['phrase']!r} ({paper['heading']})")
        found = numbers(text[0], paper)
        named = captions(paper)
        if found != set(named):
            sys.exit(f"make_papers_index: error: {paper['heading']}: found but no caption "
                     f"{sorted(found - set(named))}; captioned but not found {sorted(set(named) - found)}")
        items = [{"kind": k, "number": n, "caption": named[(k, n)]} for k, n in sorted(found, key=order)]
        doc["papers"].append({"key": paper["key"], "heading": paper["heading"], "citation": paper["citation"],
                              "items": items})
    Path(ns.out).parent.mkdir(parents=True, exist_ok=True)
    Path(ns.out).write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    print(f"make_papers_index: {sum(len(p['items']) for p in doc['papers'])} items -> {ns.out}")


if __name__ == "__main__":
    main(sys.argv[1:])
