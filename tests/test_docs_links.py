"""The README and the docs/ pages: every relative link and picture resolves inside the repository, anchors
included (GitHub's heading anchors)."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped (but ``-`` and ``_``), spaces to ``-``."""
    text = re.sub(r"[`*]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    out, seen = set(), {}
    in_code = False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            in_code = not in_code
        if in_code or not line.startswith("#"):
            continue
        s = slug(line.lstrip("#"))
        n = seen.get(s, 0)
        seen[s] = n + 1
        out.add(s if n == 0 else f"{s}-{n}")
    return out


def links(page: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)   # code blocks hold no links
    return [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t)]   # http:, mailto: are not ours


def test_slug_by_hand():
    assert slug("Every failure is one line (the fuzz suite)") == "every-failure-is-one-line-the-fuzz-suite"
    assert slug("Page, responses, analysis (`python -m laughlab study`)") == \
        "page-responses-analysis-python--m-laughlab-study"
    assert slug("DiLorenzo et al. 2008") == "dilorenzo-et-al-2008"


def test_the_pages_are_there_and_link_each_other():
    names = {p.name for p in PAGES}
    for page in ("pipeline.md", "experiments.md", "detector.md", "study.md", "benchmarks.md", "architecture.md",
                 "papers.md", "fidelity.md", "latency.md"):
        assert page in names
        assert f"(docs/{page})" in (ROOT / "README.md").read_text(), f"the README does not link docs/{page}"
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200
    assert sum(len(links(p)) for p in PAGES) > 30


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_relative_link_resolves_inside_the_repository(page):
    bad = []
    for link in links(page):
        path, _, anchor = link.partition("#")
        target = (page.parent / path).resolve() if path else page
        if ROOT not in target.parents and target != ROOT:
            bad.append(f"{link}: outside the repository")
        elif not target.exists():
            bad.append(f"{link}: no such file")
        elif anchor and target.suffix == ".md" and anchor not in anchors(target):
            bad.append(f"{link}: no heading #{anchor} in {target.name}")
    assert not bad, f"{page.name}: " + "; ".join(bad)
