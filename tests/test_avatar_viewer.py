"""Issue 28, item 2: ``view RUN --character PATH`` in a real headless Chromium (three.js + three-vrm): the
avatar's joints are where the retargeting puts them, its morphs follow the face channels."""
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from laughlab.avatar.channels import face_and_breath
from laughlab.avatar.expressions import breathing_on_bones, breathing_pose, morph_weights
from laughlab.avatar.load import load_avatar
from laughlab.avatar.retarget import animated_world, retarget
from laughlab.io.bvh import read_bvh
from laughlab.motion.skeleton import HUMANOID
from laughlab.viewer import server as V
from laughlab.viewer.browser import Page

ASSETS = Path(__file__).parent / "assets" / "avatars"
#: three-vrm 3.5.5 says this once per VRM 0.x look-at map it meets; laughlab does not use the look-at
THREE_VRM_NOTICE = "Curves of LookAtDegreeMap defined in VRM 0.0 are not supported"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    from test_avatar import run

    return run(tmp_path_factory.mktemp("avatar-viewer"), "face=facs", "input.duration_s=4")


@pytest.fixture(scope="module", params=["Godette_vrm_v4.vrm", "debug_robot.vrm"], ids=["godette-vrm0", "robot-vrm1"])
def viewed(request, run_dir):
    path = ASSETS / request.param
    httpd = V.server(run_dir, 0, path)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    page = Page(f"http://127.0.0.1:{httpd.server_address[1]}/")
    page.wait_ready(120)
    yield path, page
    page.close()
    httpd.shutdown()


def test_the_page_loads_the_vrm_through_three_vrm_without_errors(viewed):
    path, page = viewed
    assert page.eval("window.laughlab.error") is None and page.eval("window.laughlab.vrm") is True
    assert [p for p in page.problems() if THREE_VRM_NOTICE not in p] == []


@pytest.mark.parametrize("frame", [30, 140, 201])
def test_the_joints_in_the_browser_are_where_the_retargeting_puts_them(viewed, run_dir, frame):
    path, page = viewed
    av = load_avatar(path)
    _, motion, _ = read_bvh(run_dir / "motion.bvh")
    poses = motion[[frame]]
    if breathing_on_bones(av):
        ch = V._channels(run_dir)
        _, breath = face_and_breath({k: v[[frame]] for k, v in ch.items()})
        poses = breathing_pose(poses, breath, HUMANOID)
    want = animated_world(av, retarget(av, poses))[0, :, :3, 3]
    want = want * np.array([av.facing, 1, av.facing])  # the page turns a VRM 0.x avatar to face the camera
    bones = ["hips", "head", "leftHand", "rightHand", "leftFoot", "rightLowerArm", "chest"]
    nodes = [av.bones[b] for b in bones]
    page.eval(f"window.laughlab.check({frame / 60})")
    got = np.array(page.eval(f"window.laughlab.world({nodes})"))
    np.testing.assert_allclose(got, want[nodes], atol=1e-4)  # 0.1 mm: float32 in the file and the browser


def test_the_face_in_the_browser_follows_the_face_channels(viewed, run_dir):
    """Godette's 'ah' morph is the VRM 'aa' expression (ARKit jawOpen) plus a quarter of 'angry'."""
    path, page = viewed
    if "Godette" not in path.name:
        pytest.skip("the robot's expressions bind no morph")
    arkit = np.genfromtxt(run_dir / "face_arkit.csv", delimiter=",", names=True)
    av = load_avatar(path)
    face = next(n for n, names in av.morph_names.items() if "ah" in names)
    k = av.morph_names[face].index("ah")
    seen = []
    jaw = arkit["jawOpen"]
    for frame in (int(np.argmax(jaw)), 30 + int(np.argmin(jaw[30:])), 120):  # wide open, closed, between
        page.eval(f"window.laughlab.check({frame / 60})")
        influences = page.eval("window.laughlab.morphs()")
        angry = np.clip(0.5 * arkit["browDownLeft"][frame] + 0.5 * arkit["browDownRight"][frame], 0, 1)
        want = np.clip(arkit["jawOpen"][frame] + 0.25 * angry, 0, 1)
        got = [v[k] for v in influences.values() if len(v) == len(av.morph_names[face])]
        assert got and got[0] == pytest.approx(want, abs=1e-5)
        seen.append(want)
    assert max(seen) - min(seen) > 0.3  # the mouth opens and closes in these frames


def test_view_with_a_bad_character_is_one_line(run_dir, tmp_path):
    bad = tmp_path / "not.vrm"
    bad.write_text("hello")
    out = subprocess.run([sys.executable, "-m", "laughlab", "view", str(run_dir), "--character", str(bad), "--out",
                          str(tmp_path / "page")], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stderr == f"laughlab: error: {bad}: is not a glTF file (neither a glTF " \
                                                  f"binary nor glTF JSON)\n"
    assert not (tmp_path / "page").exists()
