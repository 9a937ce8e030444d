"""A review of laughlab on users' avatars (2026-11-27, /work/exp/review-avatar.md): the avatar file itself:
read once, its textures carried into character.glb, what laughlab cannot read refused in one line."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from laughlab.avatar.mannequin import mannequin_vrm
from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.io.gltf import parse_glb, read_glb

ASSETS = Path(__file__).parent / "assets" / "avatars"
GODETTE = ASSETS / "Godette_vrm_v4.vrm"
ROBOT = ASSETS / "debug_robot.vrm"


def _build(tmp_path, *overrides):
    cfg = compose_config([*overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
    return pipeline.build(cfg)


def _cli(tmp_path, *args):
    from inprocess import laughlab

    return laughlab(*args, "~output.plots", f"hydra.run.dir={tmp_path / 'run'}")   # no test here reads figures


def _one_line(out, tmp_path, says):
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().count("\n") == 0 and "Traceback" not in out.stderr, out.stderr
    assert out.stderr.startswith("laughlab: error: ") and says in out.stderr, out.stderr
    assert not (tmp_path / "run").exists()


# -- 12: the avatar checked at the start is the avatar baked at the end ---------------------------------------

@pytest.mark.parametrize("replacement", [b"not an avatar any more", "robot"])
def test_the_avatar_replaced_during_the_run_is_not_read_again(tmp_path, replacement):
    """Review 12: the gltf sink read the file again at the end: replaced by garbage, a traceback and the run lost;
    replaced by another avatar, that one baked though it was never checked."""
    path = tmp_path / "swap.vrm"
    shutil.copy(GODETTE, path)
    pipe = _build(tmp_path, "output=gltf", "face=facs", "input.duration_s=1", f"character={path}")
    path.write_bytes(ROBOT.read_bytes() if replacement == "robot" else replacement)
    pipeline.execute(pipe, tmp_path / "run")
    doc, _ = read_glb(tmp_path / "run" / "character.glb")
    godette, _ = parse_glb(GODETTE.read_bytes())
    assert len(doc["nodes"]) == len(godette["nodes"]) and "VRM" in doc["extensions"]


# -- 3: required extensions laughlab cannot read -----------------------------------------------------------------

def _robot_requiring(path: Path, *names: str) -> Path:
    from test_avatar import _robot_edited

    def edit(doc):
        doc["extensionsUsed"] = list(doc.get("extensionsUsed", [])) + list(names)
        doc["extensionsRequired"] = list(names)

    return _robot_edited(edit, path)


@pytest.mark.parametrize("ext, says", [
    ("KHR_texture_basisu", "export its textures as PNG or JPEG"),
    ("EXT_some_future_thing", "export it without that extension"),
])
def test_an_avatar_requiring_an_extension_laughlab_cannot_read_is_one_line(tmp_path, ext, says):
    """Review 3: a Draco-compressed avatar (an RPM download option) read its vertices as zeros: a blank video and a
    broken viewer page, both with exit 0.  Draco and meshopt are decoded since (tests/test_avatar_compressed.py);
    the other extensions are still refused."""
    path = _robot_requiring(tmp_path / "ext.vrm", ext)
    for output in ("output=gltf", "output=video"):
        out = _cli(tmp_path, output, "input.duration_s=1", f"character={path}")
        _one_line(out, tmp_path, f"{path}: the avatar requires the glTF extension {ext}, which laughlab cannot "
                                 f"read; {says}")


def test_required_extensions_laughlab_reads_are_fine(tmp_path):
    from laughlab.avatar.load import load_avatar

    path = _robot_requiring(tmp_path / "q.vrm", "KHR_mesh_quantization", "KHR_texture_transform",
                            "KHR_materials_unlit")
    assert load_avatar(path).kind == "vrm1"
    # mesh compression is decoded (tests/test_avatar_compressed.py); a file that lists it and compresses nothing
    # loads too, and the names are gone from the document the exports copy
    path = _robot_requiring(tmp_path / "c.vrm", "KHR_draco_mesh_compression", "EXT_meshopt_compression")
    assert load_avatar(path).doc["extensionsUsed"] == ["KHR_materials_unlit", "VRMC_vrm"]


# -- 2 and 11: a .gltf's texture files ----------------------------------------------------------------------------

def _godette_as_gltf(folder: Path) -> Path:
    """Godette as a .gltf + .bin with her images as files 'tex N.png' beside it (URIs percent-encoded), in a
    folder whose name has a space, as Blender exports 'glTF Separate'."""
    doc, binary = parse_glb(GODETTE.read_bytes())
    folder.mkdir(parents=True)
    for i, img in enumerate(doc["images"]):
        view = doc["bufferViews"][img.pop("bufferView")]
        ext = {"image/png": "png", "image/jpeg": "jpg"}[img.pop("mimeType")]
        (folder / f"tex {i}.{ext}").write_bytes(binary[view.get("byteOffset", 0):
                                                       view.get("byteOffset", 0) + view["byteLength"]])
        img["uri"] = f"tex%20{i}.{ext}"
    (folder / "Godette copy.bin").write_bytes(binary)
    doc["buffers"] = [{"uri": "Godette%20copy.bin", "byteLength": len(binary)}]
    path = folder / "Godette copy.gltf"
    path.write_text(json.dumps(doc))
    return path


def test_a_gltfs_texture_files_are_carried_into_character_glb(tmp_path):
    """Review 2: the images' relative URIs were copied as they were into character.glb, in the run's folder where
    those files are not: the avatar showed white in the viewer.  Now the baked file holds them."""
    from laughlab.avatar.load import load_avatar
    from laughlab.avatar.mesh import parts

    path = _godette_as_gltf(tmp_path / "my avatars")
    out = _cli(tmp_path, "output=gltf", "face=facs", "input.duration_s=1", f"character={path}")
    assert out.returncode == 0, out.stderr
    baked = tmp_path / "run" / "character.glb"
    doc, binary = read_glb(baked)
    assert doc["images"] and all("uri" not in img for img in doc["images"])
    for i, img in enumerate(doc["images"]):
        view = doc["bufferViews"][img["bufferView"]]
        data = binary[view.get("byteOffset", 0):view.get("byteOffset", 0) + view["byteLength"]]
        assert data == next((tmp_path / "my avatars").glob(f"tex {i}.*")).read_bytes()
        assert img["mimeType"] in ("image/png", "image/jpeg")
    # the baked file, alone in another folder, has Godette's colours (what the video and the viewer draw)
    alone = tmp_path / "elsewhere" / "character.glb"
    alone.parent.mkdir()
    alone.write_bytes(baked.read_bytes())
    got = np.concatenate([p.colours for p in parts(load_avatar(alone))])
    want = np.concatenate([p.colours for p in parts(load_avatar(GODETTE))])
    np.testing.assert_array_equal(got, want)
    # and the Khronos validator finds no error in it (the embedded images' views and MIME types)
    from test_gltf import validator_issues

    found = validator_issues(alone, tmp_path)
    assert found["numErrors"] == 0, found["messages"]


@pytest.mark.parametrize("damage, says", [
    (lambda f: f.write_bytes(np.random.default_rng(0).bytes(4000)), "is not an image laughlab can read"),
    (lambda f: f.unlink(), "cannot be read (No such file or directory); put it beside the avatar"),
    (lambda f: f.write_bytes(f.read_bytes()[:200]), "is not an image laughlab can read"),
], ids=["random-bytes", "missing", "cut-short"])
def test_a_texture_that_cannot_be_read_is_one_line_at_start_up(tmp_path, damage, says):
    """Review 11: a texture Pillow could not decode stopped a video run half-way, reported as 'cannot write the run
    folder: UnidentifiedImageError'.  Now the avatar is refused when it is loaded, naming the image."""
    path = _godette_as_gltf(tmp_path / "bad tex")
    damage(tmp_path / "bad tex" / "tex 0.png")
    for output in ("output=video", "output=gltf"):
        out = _cli(tmp_path, output, "input.duration_s=1", f"character={path}")
        _one_line(out, tmp_path, f"{path}: its texture 'tex 0.png' {says}")


# -- 10: a damaged VRM extension -----------------------------------------------------------------------------------

def _vrm1(edit):
    def make(path):
        from test_avatar import _glb

        doc, binary = parse_glb(mannequin_vrm())
        edit(doc["extensions"]["VRMC_vrm"], doc)
        path.write_bytes(_glb(doc, binary))
        return path
    return make


def _vrm0(edit):
    def make(path):
        from test_avatar import _glb

        doc, binary = parse_glb(GODETTE.read_bytes())
        edit(doc["extensions"]["VRM"], doc)
        path.write_bytes(_glb(doc, binary))
        return path
    return make


def _set(d: dict, key, value):
    d[key] = value


@pytest.mark.parametrize("make, says", [
    (_vrm1(lambda v, d: v["expressions"]["preset"]["aa"]["morphTargetBinds"][0].pop("index")),
     "its VRMC_vrm.expressions.preset.aa.morphTargetBinds[0] has no index; the file is damaged"),
    (_vrm1(lambda v, d: _set(v["humanoid"]["humanBones"], "hips", 3)),
     "its VRMC_vrm.humanoid.humanBones.hips is 3, not an object; the file is damaged"),
    (_vrm1(lambda v, d: _set(d["extensions"], "VRMC_vrm", None)),
     "its VRMC_vrm extension is null, not an object; the file is damaged"),
    (_vrm1(lambda v, d: _set(v, "expressions", {"preset": {"aa": None}})),
     "its VRMC_vrm.expressions.preset.aa is null, not an object; the file is damaged"),
    (_vrm1(lambda v, d: _set(v["humanoid"], "humanBones", [])),
     "its VRMC_vrm.humanoid.humanBones is [], not an object; the file is damaged"),
    (_vrm1(lambda v, d: _set(v["expressions"]["preset"]["aa"]["morphTargetBinds"][0], "weight", "1")),
     "its VRMC_vrm.expressions.preset.aa.morphTargetBinds[0] has weight \"1\", not a number"),
    (_vrm0(lambda v, d: v["blendShapeMaster"]["blendShapeGroups"][1]["binds"][0].pop("index")),
     "its VRM.blendShapeMaster.blendShapeGroups[1].binds[0] has no index; the file is damaged"),
    (_vrm0(lambda v, d: _set(v["blendShapeMaster"]["blendShapeGroups"][1]["binds"][0], "mesh", "0")),
     "its VRM.blendShapeMaster.blendShapeGroups[1].binds[0] has mesh \"0\", not a whole number"),
    (_vrm0(lambda v, d: _set(v["humanoid"], "humanBones", {"hips": 0})),
     "its VRM.humanoid.humanBones is {\"hips\": 0}, not a list; the file is damaged"),
    (_vrm0(lambda v, d: _set(d["images"], 0, 5)), "image 0 is not an object; the file is damaged"),
], ids=["v1-bind-no-index", "v1-bone-int", "v1-null-extension", "v1-null-expression", "v1-bones-list",
        "v1-weight-string", "v0-bind-no-index", "v0-bind-mesh-string", "v0-bones-object", "image-not-object"])
def test_a_damaged_vrm_extension_is_one_line_exit_2(tmp_path, make, says):
    """Review 10: KeyError, AttributeError and TypeError tracebacks (exit 1) where docs/avatars.md promises one
    line naming the file and what is wrong, exit 2."""
    path = make(tmp_path / "avatar.vrm")
    out = _cli(tmp_path, "output=gltf", "input.duration_s=1", f"character={path}")
    _one_line(out, tmp_path, f"{path}: {says}")


def test_odd_but_harmless_names_still_load(tmp_path):
    """A node named by a number and morph names that are not a list (both seen in the review's damaged files) are
    not bones or morph names; the avatar still loads."""
    from test_avatar import _glb

    from laughlab.avatar.load import load_avatar

    doc, binary = parse_glb(GODETTE.read_bytes())
    doc["nodes"][0]["name"] = 5
    doc["meshes"][0]["primitives"][0]["extras"]["targetNames"] = "ah"
    (tmp_path / "odd.vrm").write_bytes(_glb(doc, binary))
    av = load_avatar(tmp_path / "odd.vrm")
    assert av.kind == "vrm0" and all(len(n) == len(set(n)) or "" in n for n in av.morph_names.values())


# -- 19: python -m laughlab.avatar.mannequin DIR --------------------------------------------------------------------

def _mannequin_tool(*args):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "laughlab.avatar.mannequin", *map(str, args)], capture_output=True,
                          text=True, timeout=120)


def test_the_mannequin_tool_keeps_existing_files_and_says_errors_in_one_line(tmp_path):
    """Review 19: it replaced a user's mannequin.vrm silently, and a folder it could not make was a traceback."""
    from laughlab.avatar.mannequin import mannequin_vrm as vrm

    mine = tmp_path / "mq" / "mannequin.vrm"
    mine.parent.mkdir()
    mine.write_text("my own file")
    r = _mannequin_tool(tmp_path / "mq")
    assert r.returncode == 2 and r.stdout == "" and r.stderr == (
        f"laughlab: error: {mine} exists; pass --overwrite to replace it, or give another folder\n"), r.stderr
    assert mine.read_text() == "my own file" and not (tmp_path / "mq" / "mannequin_arkit.glb").exists()
    r = _mannequin_tool(tmp_path / "mq", "--overwrite")
    assert r.returncode == 0 and mine.read_bytes() == vrm() and sorted(p.name for p in mine.parent.iterdir()) == [
        "mannequin.vrm", "mannequin_arkit.glb"], r.stderr
    (tmp_path / "file").write_text("x")
    r = _mannequin_tool(tmp_path / "file" / "sub")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert r.stderr.startswith(f"laughlab: error: cannot write the mannequin into {tmp_path / 'file' / 'sub'} ("), \
        r.stderr


def test_a_ktx2_image_offered_beside_a_png_is_carried_along(tmp_path):
    """KHR_texture_basisu used but not required: its KTX2 images sit beside PNG fallbacks.  Pillow cannot read
    KTX2, which must not refuse the avatar; the baked file carries it as image/ktx2."""
    from laughlab.avatar.images import KTX2

    path = _godette_as_gltf(tmp_path / "basis")
    doc = json.loads(path.read_text())
    (tmp_path / "basis" / "tex.ktx2").write_bytes(KTX2 + b"\0" * 68)
    doc["images"].append({"uri": "tex.ktx2"})
    doc.setdefault("extensionsUsed", []).append("KHR_texture_basisu")
    doc["textures"][0].setdefault("extensions", {})["KHR_texture_basisu"] = {"source": len(doc["images"]) - 1}
    path.write_text(json.dumps(doc))
    out = _cli(tmp_path, "output=gltf", "face=facs", "input.duration_s=1", f"character={path}")
    assert out.returncode == 0, out.stderr
    baked, _ = read_glb(tmp_path / "run" / "character.glb")
    assert baked["images"][-1]["mimeType"] == "image/ktx2" and "uri" not in baked["images"][-1]
