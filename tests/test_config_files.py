"""laughlab's YAML files parsed once a process (core/config_files.py): compositions equal Hydra's own."""
from __future__ import annotations

import sys

import pytest
from omegaconf import OmegaConf

from laughlab.core import config_files
from laughlab.core.config import compose_config, conf_dir, register_plugin_configs


def _pkg_source():
    from hydra._internal.sources_registry import SourcesRegistry

    config_files.install()
    return SourcesRegistry.instance().resolve("pkg")


def _choices():
    """Every option of every group folder and every experiment, in as few compositions as there are experiments:
    the i-th composition takes each group's i-th option (cycling through the shorter groups)."""
    groups = {p.name: sorted(f.stem for f in p.glob("*.yaml")) for p in sorted(conf_dir().iterdir())
              if p.is_dir() and not p.name.startswith("_")}
    out = []
    for i in range(max(len(v) for v in groups.values())):
        ov = [f"{g}={names[i % len(names)]}" for g, names in groups.items()]
        out.append(ov + (["input.path=x.wav"] if "input=file" in ov else []))
    return out


def _package_source(tmp_path, monkeypatch, name: str, files: dict[str, str]):
    """A package ``name`` holding ``files`` on the path, and Hydra's (cached) reader on it."""
    pkg = tmp_path / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for file, text in files.items():
        (pkg / file).write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, name, raising=False)
    return _pkg_source()(provider="test", path=f"pkg://{name}"), pkg


def _yaml(cfg) -> str:
    return OmegaConf.to_yaml(cfg)


def test_every_option_composes_as_hydras_own_reader_composes_it(monkeypatch):
    register_plugin_configs()
    choices = _choices()
    assert len({o for ov in choices for o in ov}) > 35 and len(choices) >= 10
    cached = {}
    for ov in choices:   # twice: the second from the cache, after Hydra changed the first copies it was given
        compose_config(ov)
        cached[tuple(ov)] = _yaml(compose_config(ov))
    assert len(config_files._PARSED) > 30
    monkeypatch.setattr(_pkg_source(), "_read_config", config_files.hydra_reader)
    for ov in choices:
        assert _yaml(compose_config(ov)) == cached[tuple(ov)], ov


def test_a_file_edited_in_the_process_is_read_again_and_a_copy_changed_changes_nothing(tmp_path, monkeypatch):
    source, pkg = _package_source(tmp_path, monkeypatch, "llcfgfiles_pkg",
                                  {"a.yaml": "# @package _global_\nx: 1\nnested:\n  y: [1, 2]\n"})
    first = source.load_config("a")
    assert (first.config.x, list(first.config.nested.y), first.header["package"]) == (1, [1, 2], "_global_")
    first.config.nested.y.append(3)   # Hydra pops a file's defaults from the copy it is given
    first.header["package"] = "changed"
    again = source.load_config("a")
    assert (again.config.x, list(again.config.nested.y), again.header["package"]) == (1, [1, 2], "_global_")
    (pkg / "a.yaml").write_text("x: 2\n")
    assert source.load_config("a").config == OmegaConf.create({"x": 2})


def test_a_bad_file_is_hydras_own_error_each_time(tmp_path, monkeypatch):
    source, _ = _package_source(tmp_path, monkeypatch, "llcfgfiles_bad", {"b.yaml": "x: [1, 2\n"})
    for _ in range(2):   # not cached as a result
        with pytest.raises(Exception, match="expected ',' or ']'"):
            source.load_config("b")
