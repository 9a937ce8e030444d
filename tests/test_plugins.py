"""Plugin registry: entry points, fake plugins registered in code, a plugins folder."""
import re
from dataclasses import dataclass, field

import pytest

from laughlab import hookimpl
from laughlab.core import plugins
from laughlab.core.bases import Extractor
from laughlab.core.errors import LaughlabError

BUILTIN = {
    "source": {"synthetic", "file", "mic"},
    "extractor": {"rms"},
    "face": {"smile"},
    "body": {"shapes"},
    "scheduler": {"energy", "none"},
    "sink": {"csv", "bvh", "plots"},
}


def test_builtins_come_from_entry_points():
    reg = plugins.registry()
    for kind, names in BUILTIN.items():
        assert names <= set(reg[kind]), kind
        for name in names:
            assert "laughlab" in reg[kind][name].origin and "entry point" in reg[kind][name].origin


def test_an_installed_plugin_with_a_misspelt_hook_is_one_line(monkeypatch):
    """The plugin authors' review: a package's module with ``register_extractor`` (singular) or a hook without
    ``@hookimpl`` was ignored without a word (only "unknown extractor" later), while the same module in a
    plugins_dir is refused in one line.  Now the same checks, naming the entry point."""
    import importlib.metadata
    import types

    for text, says in (("@laughlab.hookimpl\ndef register_extractor(register):\n    pass\n",
                        "plugin typo (laughlab_typo.typo): register_extractor is not a laughlab hook"),
                       ("def register_extractors(register):\n    pass\n",
                        "plugin typo (laughlab_typo.typo): register_extractors is not marked @laughlab.hookimpl")):
        module = types.ModuleType("laughlab_typo.typo")
        exec("import laughlab\n" + text, module.__dict__)
        ep = types.SimpleNamespace(name="typo", value="laughlab_typo.typo", load=lambda m=module: m, dist=None)
        monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: [ep] if group == "laughlab" else [])
        monkeypatch.setattr(plugins, "_loaded_entry_points", False)
        with pytest.raises(LaughlabError, match="^" + re.escape(says)):
            plugins.load_entry_points()
        assert plugins.pm.get_plugin("typo") is None


@dataclass
class LoudParams:
    gain: float = 2.0

    def __post_init__(self):
        if self.gain <= 0:
            raise ValueError("gain must be > 0")


class Loud(Extractor):
    name = "loud"
    Params = LoudParams

    def step(self, block, frame):
        frame.control["mcs"] = min(1.0, float(abs(block).max(initial=0.0)) * self.params.gain)


class FakePlugin:
    @hookimpl
    def register_extractors(self, register):
        register(Loud)


@pytest.fixture
def fake():
    obj = FakePlugin()
    plugins.pm.register(obj, name="fake-loud")
    yield obj
    plugins.pm.unregister(obj)


def test_register_and_unregister_fake_plugin(fake):
    info = plugins.get("extractor", "loud")
    assert info.obj is Loud and info.origin == "registered: fake-loud"
    ext = plugins.create("extractor", "loud", {"gain": 3.0}, None)
    assert ext.params.gain == 3.0
    plugins.pm.unregister(fake)
    assert "loud" not in plugins.registry()["extractor"]
    plugins.pm.register(fake, name="fake-loud")


def test_unknown_plugin_lists_known_ones():
    with pytest.raises(LaughlabError, match=r"unknown extractor 'nope'; choose one of: .*rms"):
        plugins.get("extractor", "nope")


def test_unknown_parameter_lists_valid_ones(fake):
    with pytest.raises(LaughlabError, match=r"unknown parameter extractor.gian \(extractor=loud\) \(did you mean gain\?\); "
                                            r"valid: gain"):
        plugins.create("extractor", "loud", {"gian": 1}, None, where="extractor.loud")


def test_bad_type_and_range_are_one_line(fake):
    with pytest.raises(LaughlabError) as e:
        plugins.create("extractor", "loud", {"gain": "lots"}, None)
    assert "\n" not in str(e.value) and "gain" in str(e.value)
    with pytest.raises(LaughlabError, match="gain must be > 0"):
        plugins.create("extractor", "loud", {"gain": -1.0}, None)


def test_duplicate_names_are_refused(fake):
    other = FakePlugin()
    plugins.pm.register(other, name="fake-loud-2")
    try:
        with pytest.raises(LaughlabError, match="registered twice"):
            plugins.registry()
    finally:
        plugins.pm.unregister(other)


def test_plugins_dir(tmp_path):
    (tmp_path / "quiet_face.py").write_text(
        "import laughlab\n"
        "from laughlab.core.bases import Face\n"
        "class Quiet(Face):\n"
        "    name = 'quiet'\n"
        "    def step(self, frame):\n"
        "        frame.channels['smile'] = 0.0\n"
        "@laughlab.hookimpl\n"
        "def register_faces(register):\n"
        "    register(Quiet)\n"
    )
    loaded = plugins.load_plugin_dir(tmp_path)
    try:
        info = plugins.get("face", "quiet")
        assert info.origin.startswith("plugins dir:") and "quiet_face.py" in info.origin
    finally:
        for name in loaded:
            plugins.pm.unregister(name=name)


def test_plugins_dir_errors(tmp_path):
    with pytest.raises(LaughlabError, match="not a folder"):
        plugins.load_plugin_dir(tmp_path / "missing")
    (tmp_path / "broken.py").write_text("raise RuntimeError('boom')\n")
    with pytest.raises(LaughlabError, match="broken.py failed to import: RuntimeError: boom"):
        plugins.load_plugin_dir(tmp_path)


@dataclass
class WindowParams:
    window_samples: int = field(default=2_000_000, metadata={"large": True})   # 45 s at 44.1 kHz
    rate: float = field(default=1e7, metadata={"large": True})
    gain: float = 1.0


class Window(Extractor):
    name = "win"
    Params = WindowParams


def test_a_field_declared_large_takes_numbers_beyond_a_million_but_finite():
    """The plugin authors' review: a plugin's own default of 2,000,000 samples was refused ("magnitude at most
    1e+06") with no way out.  ``metadata={"large": True}`` lifts the bound; NaN and infinities stay refused, and
    the other fields keep it."""
    p = plugins.make_params(Window, {}, "extractor=win")
    assert (p.window_samples, p.rate) == (2_000_000, 1e7)
    assert plugins.make_params(Window, {"window_samples": 10**9}, "extractor=win").window_samples == 10**9
    with pytest.raises(LaughlabError, match=r"^bad parameter extractor=win\.rate: it must be a finite number \(got inf\)$"):
        plugins.make_params(Window, {"rate": float("inf")}, "extractor=win")
    with pytest.raises(LaughlabError, match=r"^bad parameter extractor=win\.gain: .*at most 1e\+06 \(got 2000000\.0\)$"):
        plugins.make_params(Window, {"gain": 2e6}, "extractor=win")
