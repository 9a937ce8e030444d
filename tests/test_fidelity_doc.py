"""docs/fidelity.md: a row for every numbered equation, listing and figure of the thesis, and only real tests cited."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "fidelity.md").read_text()
THESIS = (Path(__file__).resolve().parents[2] / "shared" / "papers" / "000_a3fcf64a993261c7.txt")


def thesis_section() -> str:
    return DOC.split("## van Duijn 2014")[1].split("\n## ")[0]


def test_every_numbered_equation_figure_and_listing_of_the_thesis_has_a_row():
    rows = [line for line in thesis_section().splitlines() if line.startswith("| ")]
    firsts = " ".join(line.split("|")[1] for line in rows)
    if THESIS.exists():  # the numbers as the thesis prints them
        text = THESIS.read_text()
        equations = sorted(set(re.findall(r"^\((\d\.\d)\)$", text, re.M)))
        figures = sorted(set(re.findall(r"^Figure (\d\.\d):", text, re.M)))
    else:  # the numbers of the thesis, for a checkout without shared/
        equations = ["3.1", "3.2", "3.3", "3.4", "4.1"]
        figures = [f"{c}.{i}" for c, n in ((1, 2), (2, 4), (3, 8), (4, 2), (5, 2)) for i in range(1, n + 1)]
    assert equations == ["3.1", "3.2", "3.3", "3.4", "4.1"]
    assert len(figures) == 18
    for eq in equations:
        assert f"Eq. {eq}" in firsts, eq
    for fig in figures:
        assert f"Fig. {fig} " in firsts, fig
    for listing in ("3.1.1 mapping", "3.1.1 calibration", "3.2.2 smoothing", "5.2 ", "5.3 ", "5.4 ", "5.5 "):
        assert listing in firsts, listing


def cited_tests():
    """``file.py::name`` references; a bare ``::name`` after one belongs to the same file."""
    out, current = set(), None
    for file, name in re.findall(r"(test_[a-z0-9_]+\.py)?::([a-zA-Z0-9_]+)", DOC):
        current = file or current
        out.add((current, name))
    return sorted(out)


def test_the_tests_it_cites_exist():
    assert len(cited_tests()) > 40
    missing = []
    for file, name in cited_tests():
        src = ROOT / "tests" / file
        if not src.exists() or not re.search(rf"^def {name}\(", src.read_text(), re.M):
            missing.append(f"{file}::{name}")
    assert not missing


def test_every_row_has_a_status():
    statuses = ("MATCH", "DEVIATION", "NOT IMPLEMENTED", "NOT GIVEN", "*our reading*", "partly")
    rows = [line for line in DOC.splitlines() if line.startswith("| ") and not line.startswith("| item")]
    assert len(rows) > 50
    bad = [r for r in rows if not r.split("|")[3].strip().startswith(statuses)]
    assert not bad
