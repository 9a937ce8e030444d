"""Compressed avatars (Ready Player Me's Draco GLBs, gltfpack's and gltf-transform's meshopt ones): decoded when
loaded (laughlab/avatar/compressed.py), so the mesh, the run and character.glb are those of the uncompressed file.
The compressed copies are made here from the test avatars with the real encoders (tests/compress_avatar.py)."""
from pathlib import Path

import numpy as np
import pytest
from compress_avatar import DRACO, MESHOPT, draco, glb, meshopt
from test_avatar import run
from test_avatar_files import _cli, _one_line

from laughlab.avatar.load import load_avatar
from laughlab.avatar.mesh import accessor, parts
from laughlab.io.gltf import accessor_array, parse_glb, read_glb

ASSETS = Path(__file__).parent / "assets" / "avatars"
GODETTE = ASSETS / "Godette_vrm_v4.vrm"
ROBOT = ASSETS / "debug_robot.vrm"


def _rotated(tris: np.ndarray) -> np.ndarray:
    """Each triangle turned to start at its smallest vertex (meshopt's index codec may turn a triangle; the
    winding, and so the face, stays)."""
    k = np.argmin(tris, axis=1)
    return np.stack([tris[np.arange(len(tris)), (k + j) % 3] for j in range(3)], axis=1)


def _uvs(av) -> list:
    """TEXCOORD_0 of every primitive of every mesh node, in the order of :func:`parts`."""
    return [accessor(av, p["attributes"]["TEXCOORD_0"]) for nd in av.doc["nodes"] if "mesh" in nd
            for p in av.doc["meshes"][nd["mesh"]]["primitives"] if "TEXCOORD_0" in p["attributes"]]


@pytest.mark.parametrize("avatar", [ROBOT, GODETTE], ids=["robot", "godette"])
def test_a_draco_avatar_decodes_to_the_uncompressed_mesh(avatar, tmp_path):
    """Positions within Draco's quantisation step (14 bits over the primitive's largest extent: half a step each
    way), normals within 10-bit octahedral quantisation, UVs within 12 bits, joints exact, weights and the
    (uncompressed) morph targets as they were; the triangles the same (Draco's sequential coder keeps the order).
    Weights whose sums a quantising encoder left 0.1% off sum to 1 again (glTF 2.0, 3.7.3.3)."""
    plain, packed = load_avatar(avatar), load_avatar(draco(avatar, tmp_path / "d.glb", weights_off=1e-3))
    for prim in (p for m in packed.doc["meshes"] for p in m["primitives"] if "WEIGHTS_0" in p["attributes"]):
        assert np.abs(accessor(packed, prim["attributes"]["WEIGHTS_0"]).sum(axis=1) - 1).max() < 1e-6
    original, decoded = parts(plain), parts(packed)
    assert len(original) == len(decoded) and len(original) > 0
    for uv, uv2 in zip(_uvs(plain), _uvs(packed)):
        assert np.abs(uv - uv2).max() <= 0.5 * np.ptp(uv, axis=0).max() / (2 ** 12 - 1) * 1.001 + 1e-7
    for a, b in zip(original, decoded):
        step = np.ptp(a.positions, axis=0).max() / (2 ** 14 - 1)
        assert np.abs(a.positions - b.positions).max() <= 0.5 * step * 1.001 + 1e-7
        assert np.abs(a.normals - b.normals).max() < 4 / 2 ** 10
        assert (a.triangles == b.triangles).all()
        assert np.array_equal(a.morphs, b.morphs)
        if a.weights is not None:
            assert np.array_equal(a.skin_slots, b.skin_slots) and np.allclose(a.weights, b.weights, atol=1e-6)


def test_an_edgebreaker_draco_mesh_has_the_same_triangles(tmp_path):
    """Draco's edgebreaker coder (what encoders use without morph targets) renumbers the vertices: the triangles,
    as the points they join, are the same within the quantisation."""
    original, decoded = parts(load_avatar(ROBOT)), parts(load_avatar(draco(ROBOT, tmp_path / "e.glb",
                                                                           preserve_order=False)))
    for a, b in zip(original, decoded):
        soup = [_soup(p.positions[p.triangles]) for p in (a, b)]
        assert soup[0].shape == soup[1].shape and np.abs(soup[0] - soup[1]).max() <= 1e-3


def _soup(tris: np.ndarray) -> np.ndarray:
    """Triangles (T, 3, 3) as rows of their three points rounded to 0.1 mm, each turned to start at its least point
    (the winding kept), the rows sorted."""
    tris = np.round(tris, 4)
    rows = []
    for t in tris:
        k = min(range(3), key=lambda j: tuple(t[j]))
        rows.append(np.roll(t, -k, axis=0).reshape(-1))
    return np.array(sorted(rows, key=tuple))


@pytest.mark.parametrize("avatar", [ROBOT, GODETTE], ids=["robot", "godette"])
def test_a_meshopt_avatar_decodes_to_the_same_bytes(avatar, tmp_path):
    """meshopt's codecs are lossless: every accessor reads as in the uncompressed file, the triangles at most turned
    (same winding); the fallback buffer and the extension are gone from the document laughlab keeps."""
    av = load_avatar(meshopt(avatar, tmp_path / "m.glb"))
    assert MESHOPT not in av.doc.get("extensionsUsed", []) and len(av.doc["buffers"]) == 1
    for a, b in zip(parts(load_avatar(avatar)), parts(av)):
        assert np.array_equal(a.positions, b.positions) and np.array_equal(a.normals, b.normals)
        assert np.array_equal(a.colours, b.colours) and np.array_equal(a.morphs, b.morphs)
        assert np.array_equal(_rotated(a.triangles), _rotated(b.triangles))


def test_a_meshopt_gltf_with_its_fallback_buffer_loads(tmp_path):
    """A ``.gltf`` beside its ``.bin``, with gltfpack's second buffer: the fallback, tagged so and without data
    (EXT_meshopt_compression, *Fallback buffers*), is not counted as a second buffer laughlab cannot read."""
    import json

    doc, binary = parse_glb(meshopt(ROBOT, tmp_path / "m.glb").read_bytes())
    (tmp_path / "m.bin").write_bytes(binary)
    doc["buffers"][0]["uri"] = "m.bin"
    (tmp_path / "m.gltf").write_text(json.dumps(doc))
    for a, b in zip(parts(load_avatar(ROBOT)), parts(load_avatar(tmp_path / "m.gltf"))):
        assert np.array_equal(a.positions, b.positions) and np.array_equal(a.normals, b.normals)


@pytest.fixture(scope="module")
def copies(tmp_path_factory):
    """Godette's Draco and meshopt copies as the encoders make them (made once: the tests below only read them)."""
    d = tmp_path_factory.mktemp("copies")
    return {"draco": draco(GODETTE, d / "draco.vrm"), "meshopt": meshopt(GODETTE, d / "meshopt.vrm")}


@pytest.fixture(scope="module")
def godette_runs(tmp_path_factory, copies):
    """The same 2 s run baked on Godette, on her Draco copy (weights 0.1% off, as a quantising encoder leaves them)
    and on her meshopt copy; and the Khronos validator's issues with plain Godette (the same for both kinds)."""
    from test_gltf import validator_issues

    d = tmp_path_factory.mktemp("compressed")
    files = {"plain": GODETTE, "draco": draco(GODETTE, d / "draco.vrm", weights_off=1e-3),
             "meshopt": copies["meshopt"]}
    runs = {k: run(d / k, "output=gltf", "face=facs", "input.duration_s=2", "~output.plots", f"character={f}")
            for k, f in files.items()}   # the runs' character.glb are compared, not their figures
    return runs, validator_issues(GODETTE, d)


def _animation(path: Path) -> list:
    doc, binary = read_glb(path)
    anim = doc["animations"][0]
    return [(c["target"], accessor_array(doc, binary, anim["samplers"][c["sampler"]]["output"]))
            for c in anim["channels"]]


@pytest.mark.parametrize("kind", ["draco", "meshopt"])
def test_a_run_on_a_compressed_avatar_animates_as_on_the_uncompressed_one(godette_runs, kind, tmp_path):
    """character.glb of the compressed copy: the same channels on the same nodes with the same values (joints and
    morph weights), no compression extension required any more, and the Khronos validator finds no error and
    no warning the uncompressed avatar does not have."""
    from test_gltf import validator_issues

    runs, godette_issues = godette_runs
    path = runs[kind] / "character.glb"
    plain, ours = _animation(runs["plain"] / "character.glb"), _animation(path)
    assert [t for t, _ in ours] == [t for t, _ in plain]
    assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(ours, plain))
    doc, _ = read_glb(path)
    assert {DRACO, MESHOPT}.isdisjoint(doc.get("extensionsUsed", []) + doc.get("extensionsRequired", []))
    found = validator_issues(path, tmp_path)
    assert found["numErrors"] == 0, found["messages"]
    codes = {m["code"] for m in found["messages"] if m["severity"] <= 1}
    theirs = {m["code"] for m in godette_issues["messages"] if m["severity"] <= 1}
    assert codes <= theirs, codes - theirs


def _corrupt(path: Path, kind: str) -> Path:
    """The compressed data of the first mesh's first primitive (Draco) or of the first compressed bufferView
    (meshopt) overwritten with other bytes of the same length; ``huge``: that bufferView declared 4.3 GB long."""
    doc, binary = parse_glb(path.read_bytes())
    if kind == "draco":
        at = doc["bufferViews"][doc["meshes"][0]["primitives"][0]["extensions"][DRACO]["bufferView"]]
    else:
        at = next(v["extensions"][MESHOPT] for v in doc["bufferViews"] if "extensions" in v)
    start = at.get("byteOffset", 0)
    if kind == "huge":   # a view that declares 4.3 GB of decoded data (its byteLength is declared, not stored)
        view = next(v for v in doc["bufferViews"] if "extensions" in v)
        at["count"], view["byteLength"] = 2 ** 32 // at["byteStride"], 2 ** 32
    else:
        binary = binary[:start] + b"\x5a" * at["byteLength"] + binary[start + at["byteLength"]:]
    path.write_bytes(glb(doc, binary))
    return path


@pytest.mark.parametrize("kind, says", [
    ("draco", f"mesh 0's primitive 0's {DRACO} data does not decode"),
    ("meshopt", f"'s {MESHOPT} data does not decode"),
    ("huge", "its meshopt-compressed data would decode to 4.3 GB; laughlab decodes avatars up to 1.1 GB"),
])
def test_a_corrupt_compressed_buffer_is_one_line_and_writes_nothing(tmp_path, kind, says):
    path = _corrupt((draco if kind == "draco" else meshopt)(ROBOT, tmp_path / f"{kind}.vrm"), kind)
    for output in ("output=gltf", "output=video"):
        out = _cli(tmp_path, output, "input.duration_s=1", f"character={path}")
        _one_line(out, tmp_path, says)
        assert out.stderr.startswith(f"laughlab: error: {path}: ")
        assert "the file is damaged" in out.stderr or kind == "huge"


def test_draco_weights_sum_to_one_in_character_glb(tmp_path):
    """laughlab's mannequin as a plain glTF, its weights Draco-compressed 0.1% off as a quantising encoder leaves
    them: the Khronos validator rejected the exported file (ACCESSOR_WEIGHTS_NON_NORMALIZED, seen on gltf-transform's
    Draco output) before the decoded weights were scaled to sum to 1; now it finds nothing."""
    from test_gltf import validator_issues

    from laughlab.avatar.mannequin import mannequin_arkit_glb

    (tmp_path / "m.glb").write_bytes(mannequin_arkit_glb())
    path = draco(tmp_path / "m.glb", tmp_path / "draco.glb", weights_off=1e-3)
    out = run(tmp_path / "run", "output=gltf", "face=facs", "input.duration_s=1", f"character={path}")
    found = validator_issues(out / "character.glb", tmp_path)
    assert (found["numErrors"], found["numWarnings"]) == (0, 0), found["messages"]


def test_the_video_draws_a_compressed_avatar_as_the_uncompressed_one(tmp_path, copies):
    """The software renderer's frames of Godette's compressed copies, in the rest pose and in a bent pose with a
    morph on: meshopt's (lossless) the same pixels; Draco's within its quantisation (a pixel at an edge may flip).
    And ``output=video`` on the Draco copy runs."""
    from laughlab.motion.skeleton import HUMANOID, rest_pose
    from laughlab.render.avatar_view import AvatarRenderer

    bent = rest_pose().copy()
    bent[3:] += np.random.default_rng(1).normal(0.0, 10.0, bent[3:].shape)
    frames = {}
    for name, path in (("plain", GODETTE), ("meshopt", copies["meshopt"]), ("draco", copies["draco"])):
        r = AvatarRenderer(load_avatar(path), HUMANOID, 320, 240, supersample=1)
        frames[name] = [r.render(rest_pose(), {}), r.render(bent, {"jawOpen": 0.8})]
    for plain, packed in zip(frames["plain"], frames["meshopt"]):
        assert np.array_equal(plain, packed)
    for plain, packed in zip(frames["plain"], frames["draco"]):
        differ = np.abs(plain.astype(int) - packed.astype(int)).max(axis=2) > 8
        assert differ.mean() < 0.002, differ.mean()
    out = _cli(tmp_path, "output=video", "face=facs", "input.duration_s=1", f"character={copies['draco']}",
               "output.video.supersample=1")
    assert out.returncode == 0 and (tmp_path / "run" / "video.mp4").stat().st_size > 10_000, out.stderr


@pytest.fixture(scope="module")
def browser_run(tmp_path_factory):
    """A 3 s run (no figures: the page shows none) for the page to play on each copy."""
    return run(tmp_path_factory.mktemp("browser") / "run", "face=facs", "input.duration_s=3", "~output.plots")


@pytest.mark.browser
@pytest.mark.parametrize("kind", ["draco", "meshopt"])
def test_the_browser_plays_a_compressed_avatar(kind, copies, browser_run):
    """``view RUN --character`` a compressed copy of Godette: three.js and three-vrm load the page's character.glb
    (decoded by laughlab; the page has no Draco or meshopt decoder) without an error, and her joints are where the
    retargeting puts them."""
    import threading

    from test_avatar_viewer import THREE_VRM_NOTICE, joints_where_the_retargeting_puts_them

    from laughlab.viewer import server as V
    from laughlab.viewer.browser import Page

    path, run_dir = copies[kind], browser_run
    httpd = V.server(run_dir, 0, path)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    page = Page(f"http://127.0.0.1:{httpd.server_address[1]}/")
    try:
        page.wait_ready(120)
        assert page.eval("window.laughlab.error") is None and page.eval("window.laughlab.vrm") is True
        assert [p for p in page.problems() if THREE_VRM_NOTICE not in p] == []
        joints_where_the_retargeting_puts_them(page, path, run_dir, 140)
    finally:
        page.close()
        httpd.shutdown()
