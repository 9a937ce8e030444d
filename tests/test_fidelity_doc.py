"""docs/fidelity.md against the papers' index and the code: a row for every numbered equation, figure,
table and listing of each paper, and every test, file and symbol a row cites exists.

The numbers come from ``tests/data/papers_index.json`` (made once from the papers' texts by
``tools/make_papers_index.py``), so this test needs nothing outside the repository.
"""
import ast
import json
import re
from functools import lru_cache
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "fidelity.md").read_text()
INDEX = json.loads((ROOT / "tests" / "data" / "papers_index.json").read_text())
PAPERS = {p["key"]: p for p in INDEX["papers"]}
CODE_DIRS = ("laughlab", "plugins", "experiments")
REPO_DIRS = (*CODE_DIRS, "conf", "tests", "docs", "benchmarks", "reports", "tools")


def section(heading: str) -> str:
    parts = [s for s in DOC.split("\n## ")[1:] if s.startswith(heading)]
    assert len(parts) == 1, f"docs/fidelity.md needs one section '## {heading}...'"
    return parts[0]


def rows(text: str = DOC) -> list[list[str]]:
    """The table rows (cells stripped), headers and rules left out."""
    out = []
    for line in text.splitlines():
        if line.startswith("| ") and not line.startswith(("| item", "|---")):
            out.append([c.strip() for c in line.strip().strip("|").split(" | ")])
    return out


def labels(cell: str) -> set[tuple[str, str]]:
    """The (kind, number) a row's first cell names: ``Eq. 3.1``, ``Eq. 6-1``, ``Eqs. 4-6`` (a range),
    ``Fig. 3``, ``Figs. 5-7``, ``Table 1``."""
    out = set()
    for kind, word in (("equation", "Eq"), ("figure", "Fig"), ("table", "Table")):
        for a, b in re.findall(rf"\b{word}s\.? (\d+)-(\d+)", cell):
            out |= {(kind, str(n)) for n in range(int(a), int(b) + 1)}
        out |= {(kind, n) for n in re.findall(rf"\b{word}\.? (\d+(?:\.\d+|-\d+)?)(?![\d.])", cell)}
    return out


def covered(paper: dict) -> set[tuple[str, str]]:
    text = section(paper["heading"])
    got = set()
    for r in rows(text):
        got |= labels(r[0])
        m = re.match(r"(\d\.\d(?:\.\d)?) ", r[0])
        if m and "### Code listings" in text and text.index(r[0]) > text.index("### Code listings"):
            got.add(("listing", m.group(1)))
    return got


def test_the_index_holds_every_paper_and_its_numbering():
    assert sorted(PAPERS) == ["dilorenzo2008", "ding2014", "unuma1995", "vanduijn2014"]
    count = lambda key, kind: sum(i["kind"] == kind for i in PAPERS[key]["items"])  # noqa: E731
    assert [i["number"] for i in PAPERS["vanduijn2014"]["items"] if i["kind"] == "equation"] == \
        ["3.1", "3.2", "3.3", "3.4", "4.1"]
    assert count("vanduijn2014", "figure") == 18 and count("vanduijn2014", "listing") == 6
    assert count("dilorenzo2008", "equation") == 4 and count("dilorenzo2008", "figure") == 10
    assert count("unuma1995", "equation") == 10 and count("unuma1995", "figure") == 10
    assert count("ding2014", "equation") == 8 and count("ding2014", "figure") == 8 and count("ding2014", "table") == 1
    assert all(i["caption"] for p in PAPERS.values() for i in p["items"])


@pytest.mark.parametrize("key", sorted(PAPERS))
def test_every_indexed_item_of_each_paper_has_a_row(key):
    paper = PAPERS[key]
    wanted = {(i["kind"], i["number"]) for i in paper["items"]}
    assert not sorted(wanted - covered(paper)), f"{paper['heading']}: no row in docs/fidelity.md"


@pytest.mark.parametrize("key", sorted(PAPERS))
def test_no_row_names_an_item_the_paper_lacks(key):
    paper = PAPERS[key]
    wanted = {(i["kind"], i["number"]) for i in paper["items"]}
    assert not sorted(covered(paper) - wanted), f"{paper['heading']}: rows for numbers the paper does not have"


def test_the_label_reader_by_hand():
    assert labels("Eq. 3.1 RMS") == {("equation", "3.1")}
    assert labels("Eqs. 4-6 total cost") == {("equation", "4"), ("equation", "5"), ("equation", "6")}
    assert labels("Eq. 6-1 rescaled") == {("equation", "6-1")}
    assert labels("6.1 / Fig. 5 linearised") == {("figure", "5")}
    assert labels("Figs. 5-7 lips, Table 1") == {("figure", "5"), ("figure", "6"), ("figure", "7"), ("table", "1")}
    assert labels("5.1 passive element") == set()


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
    files = set(re.findall(r"`(test_[a-z0-9_]+\.py)", DOC))
    missing += [f for f in files if not (ROOT / "tests" / f).exists()]
    assert not missing


# --- files and symbols ---------------------------------------------------------------------------


@lru_cache(maxsize=None)
def code_files() -> dict[str, list[Path]]:
    out: dict[str, list[Path]] = {}
    for d in CODE_DIRS:
        for p in (ROOT / d).rglob("*"):
            if p.is_file() and "__pycache__" not in p.parts:
                out.setdefault(p.name, []).append(p)
    return out


@lru_cache(maxsize=None)
def names(path: Path) -> dict[str, set[str]]:
    """Top-level names of a module (``""``) and the members of each top-level class."""
    tree = ast.parse(path.read_text())
    out: dict[str, set[str]] = {"": set()}

    def bound(node) -> set[str]:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            return {node.name}
        if isinstance(node, ast.Assign):
            return {t.id for t in node.targets if isinstance(t, ast.Name)}
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            return {node.target.id}
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            return {(a.asname or a.name).split(".")[0] for a in node.names}
        return set()

    for node in tree.body:
        out[""] |= bound(node)
        if isinstance(node, ast.ClassDef):
            out[node.name] = set().union(*(bound(n) for n in node.body))
    return out


def has_symbol(path: Path, symbol: str) -> bool:
    symbol = re.match(r"[\w.]+", symbol).group(0)   # PRESETS["cough"] -> PRESETS
    parts = symbol.split(".")
    table = names(path)
    if len(parts) == 1:
        return parts[0] in table[""]
    return parts[0] in table and parts[1] in table[parts[0]]


def has_key(path: Path, dotted: str) -> bool:
    data = yaml.safe_load(path.read_text()) if path.suffix == ".yaml" else json.loads(path.read_text())
    for part in dotted.split("."):
        if not isinstance(data, dict) or part not in data:
            return False
        data = data[part]
    return True


def resolve(name: str) -> list[Path]:
    """A cited path: from the repository's root, or a bare file name unique among the code folders."""
    if "/" in name:
        return sorted(ROOT.glob(name)) if "*" in name else ([ROOT / name] if (ROOT / name).exists() else [])
    if name.startswith("test"):
        return [ROOT / "tests" / name] if (ROOT / "tests" / name).exists() else []
    return code_files().get(name, [])


CITE = re.compile(r"^([\w./*-]+\.(?:py|yaml|json|bvh))(?:: (.+))?$")
CLASS_MEMBER = re.compile(r"^([A-Z][a-z]+(?:[A-Z][a-z0-9]*)*)(?:\.(\w+))?$")


def citations() -> list[str]:
    return sorted({c for r in rows() for cell in r[1:] for c in re.findall(r"`([^`]+)`", cell)})


def test_every_file_and_symbol_it_cites_exists():
    problems, checked = [], 0
    for cite in citations():
        m = CITE.match(cite)
        if m:
            path, symbols = m.groups()
            if "/" in path and path.split("/")[0] not in REPO_DIRS:
                continue                         # a run's output (plots/..., a results file), not the repository's
            found = resolve(path)
            if "/" not in path and path.endswith(".json") and not found:
                continue                         # an output file named by itself (hill_fit.json, metrics.json)
            if len(found) != 1 and "*" not in path:
                problems.append(f"{cite}: {len(found)} files")
                continue
            if not found:
                problems.append(f"{cite}: no file")
                continue
            checked += 1
            for sym in (s.strip() for s in (symbols or "").split(",") if s.strip()):
                ok = has_symbol(found[0], sym) if path.endswith(".py") else has_key(found[0], sym)
                problems += [] if ok else [f"{cite}: no {sym}"]
        elif CLASS_MEMBER.match(cite) and any(c.isupper() for c in cite[1:].split(".")[0]) or \
                re.match(r"^[A-Z][a-z]+\.\w+$", cite):
            cls, member = CLASS_MEMBER.match(cite).groups() if CLASS_MEMBER.match(cite) else cite.split(".")
            homes = [p for ps in code_files().values() for p in ps if p.suffix == ".py" and cls in names(p)]
            checked += 1
            if not homes or (member and not any(member in names(p)[cls] for p in homes)):
                problems.append(f"{cite}: no such class or member in {', '.join(CODE_DIRS)}")
    assert checked > 150
    assert not problems, "\n".join(problems)


def test_the_symbol_checker_by_hand(tmp_path):
    mod = tmp_path / "m.py"
    mod.write_text("from x import y as z\nA = 1\nB: int = 2\nclass C:\n    k: float = 1.0\n    def f(self): ...\n")
    assert all(has_symbol(mod, s) for s in ("A", "B", "z", "C", "C.k", "C.f", 'A["x"]'))
    assert not any(has_symbol(mod, s) for s in ("D", "C.g", "y", "k"))
    conf = tmp_path / "c.yaml"
    conf.write_text("torso:\n  lung:\n    k: 1\n")
    assert has_key(conf, "torso.lung.k") and not has_key(conf, "torso.k")


def test_every_row_has_a_status():
    statuses = ("MATCH", "DEVIATION", "NOT IMPLEMENTED", "NOT GIVEN", "*our reading*", "partly")
    assert len(rows()) > 50
    bad = [r for r in rows() if not r[2].startswith(statuses)]
    assert not bad
