"""``python -m laughlab view``: the character in a real headless Chromium, in sync with the audio (issue 13, item 3)."""
import io
import json
import subprocess
import sys
import threading

import numpy as np
import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.viewer import server as V
from laughlab.viewer.browser import Page


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer")
    cfg = compose_config(["face=facs", "input.duration_s=6"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
    pipeline.execute(pipeline.build(cfg), out)
    return out


@pytest.fixture(scope="module")
def page(run_dir):
    httpd = V.server(run_dir, 0)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    p = Page(f"http://127.0.0.1:{httpd.server_address[1]}/")
    p.wait_ready()
    yield p
    p.close()
    httpd.shutdown()


@pytest.mark.browser
def test_the_page_loads_without_console_errors(page):
    assert page.eval("window.laughlab.error") is None
    assert page.problems() == []


@pytest.mark.browser
@pytest.mark.parametrize("t", [2.5, 0.4, 5.25])
def test_the_animation_follows_the_audio_clock_within_a_frame_after_a_seek(page, t):
    got = page.eval(f"window.laughlab.check({t})")
    assert got["audio"] == pytest.approx(t, abs=0.01)  # the audio really seeked (byte ranges served)
    assert abs(got["anim"] - got["audio"]) <= 1.0 / got["fps"]


@pytest.mark.browser
def test_a_screenshot_shows_the_character(page):
    from PIL import Image

    page.eval("window.laughlab.check(3.0)")
    png = page.screenshot()
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    view = img[: int(0.6 * img.shape[0])]
    background = np.array([0x2a, 0x30, 0x40])
    figure = np.abs(view - background).sum(axis=2) > 60
    assert figure.mean() > 0.05  # the character and the floor cover a good part of the view
    r, g, b = view[..., 0], view[..., 1], view[..., 2]
    skin = figure & (r > g + 20) & (g > b) & (r > 150)
    shirt = figure & (b > r + 25)
    assert skin.sum() > 200 and shirt.sum() > 2000  # a face and hands, a blue shirt: not only a floor


def test_bad_input_is_one_line(tmp_path, run_dir):
    r = subprocess.run([sys.executable, "-m", "laughlab", "view", str(tmp_path / "nope")], capture_output=True,
                       text=True)
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "no run directory" in r.stderr
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "channels.csv").write_text("time\n0\n")
    r = subprocess.run([sys.executable, "-m", "laughlab", "view", str(tmp_path / "half")], capture_output=True,
                       text=True)
    assert r.returncode == 2 and "motion.bvh, events.csv" in r.stderr and "Traceback" not in r.stderr


def test_a_port_in_use_gives_a_free_one(run_dir):
    first = V.server(run_dir, 0)
    try:
        second = V.server(run_dir, first.server_address[1])
        assert second.server_address[1] != first.server_address[1]
        second.server_close()
    finally:
        first.server_close()


def test_the_page_can_be_written_for_static_hosting(run_dir, tmp_path):
    out = V.write(run_dir, tmp_path / "site")
    names = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert {"index.html", "viewer.js", "run.json", "character.glb", "audio.wav", "vendor/three/LICENSE",
            "vendor/three/build/three.module.min.js"} <= names
    run = json.loads((out / "run.json").read_text())
    assert run["fps"] == 60.0 and run["duration"] == pytest.approx(6.0) and run["clips"]
    with pytest.raises(Exception, match="not an empty folder"):
        V.write(run_dir, tmp_path / "site")
