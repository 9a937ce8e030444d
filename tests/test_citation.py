"""CITATION.cff and LICENSE: researchers cite laughlab and the papers it implements; the file is what GitHub and
Zotero read (validated by hand with cffconvert 2.0 against CFF 1.2.0's schema, 2026-11-29: "valid")."""
import re
import tomllib
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def test_the_citation_names_this_version_and_licence_and_every_paper_as_docs_papers_md_cites_it():
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    assert {"message", "title", "authors"} <= set(cff)
    # laughlab's own code is MIT; the package also bundles YAMNet's Apache-2.0 model (pyproject's expression)
    assert cff["version"] == project["version"] and cff["license"] == "MIT"
    assert project["license"] == "MIT AND Apache-2.0"
    papers = (ROOT / "docs" / "papers.md").read_text()
    cited = papers.split("## The papers", 1)[1].split("##", 1)[0]
    assert len(cff["references"]) == 4 == len(re.findall(r"^\d\. \*\*", cited, re.M))
    for ref in cff["references"]:
        assert ref["title"] in cited.replace("\n   ", " "), ref["title"]
        assert f"{ref['authors'][0]['family-names']}" in cited and str(ref["year"]) in cited


def test_the_licence_is_the_one_pyproject_declares():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License\n") and "Copyright (c) 2026 The laughlab developers" in text
