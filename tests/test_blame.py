"""core.blame: an exception a plugin raises names the plugin, its class and file, and the frame; built-in or not."""
import pickle

import pytest

from laughlab.core import blame, plugins
from laughlab.core.bases import Context
from laughlab.core.errors import LaughlabError


def _raised(fn):
    try:
        fn()
    except BaseException as exc:  # noqa: BLE001 - the exception under test
        return exc
    raise AssertionError("did not raise")


def test_a_built_in_plugins_exception_asks_for_a_report_and_survives_pickling():
    face = plugins.create("face", "smile", {}, Context())
    exc = _raised(lambda: face.step(None))          # no frame: laughlab's own code fails inside step()
    blame.mark(exc, [None, object(), face], 5, 60.0)
    line = blame.line(exc)
    assert line.startswith(f"face 'smile' ({blame._source_file(type(face))}, {type(face).__name__}.step) at frame 5 "
                           f"(0.08 s) raised AttributeError: ")
    assert line.endswith("(a bug in laughlab: please report it with the lines above)")
    assert blame.trace(exc).startswith("Traceback (most recent call last):\n")
    assert "test_blame.py" not in blame.trace(exc)   # from the plugin's own call on
    back = pickle.loads(pickle.dumps(exc))          # a trial's exception crosses from a worker process
    assert blame.line(back) == line and blame.trace(back) == blame.trace(exc)


def test_a_third_party_plugin_outside_step_names_its_method_not_the_frame():
    from laughlab import Face

    class Grin(Face):
        name = "grin"

        def step(self, frame):
            pass

        def reset(self):
            {}["state"]

    face = Grin()
    exc = _raised(face.reset)
    blame.mark(exc, [face], 3, 60.0)      # a frame number, but reset() is no frame's step
    assert blame.line(exc) == (f"face 'grin' ({__file__}, Grin.reset) raised KeyError: 'state' (the lines above "
                               "are from the plugin's code)")


@pytest.mark.parametrize("exc", [LaughlabError("bad input"), OSError(28, "No space left on device"),
                                 KeyboardInterrupt()])
def test_one_line_errors_and_interrupts_are_left_as_they_are(exc):
    face = plugins.create("face", "smile", {}, Context())

    def step(frame):
        raise exc
    face.step = step
    caught = _raised(lambda: face.step(None))
    blame.mark(caught, [face], 3, 60.0)
    assert blame.line(caught) is None and blame.trace(caught) == ""


def test_an_exception_of_no_plugin_is_left_as_it_is():
    face = plugins.create("face", "smile", {}, Context())
    exc = _raised(lambda: 1 / 0)
    blame.mark(exc, [face], 3, 60.0)
    assert blame.line(exc) is None


def test_out_of_memory_is_the_machines_limit_not_the_plugins_bug():
    from laughlab import Face

    class Big(Face):
        name = "big"

        def step(self, frame):
            import numpy as np

            np.empty((10**8, 10**8))   # numpy's MemoryError says what it asked for: a plugin's bug shows in it

    face = Big()
    exc = _raised(lambda: face.step(None))
    blame.mark(exc, [face], 3, 60.0)
    assert blame.line(exc).startswith(f"face 'big' ({__file__}, Big.step) at frame 3 (0.05 s) ran out of memory "
                                      "(Unable to allocate 71.1 PiB for an array with shape (100000000, 100000000)")
    assert "bug" not in blame.line(exc) and "lines above" not in blame.line(exc)
    assert blame.trace(exc) == ""    # no traceback is printed
