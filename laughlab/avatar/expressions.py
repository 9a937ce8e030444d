"""The face's ARKit weights and the body's breathing on an avatar: morph targets, VRM expressions, spine bones.

Three routes, in this order:

1. **ARKit names.**  A morph target named as an ARKit blendshape (``jawOpen``, ``eyeBlinkLeft``,
   ARKit's raw ``eyeBlink_L``, ...; case and a ``prefix.`` such as ``blendShape1.`` ignored) takes
   that weight.
2. **VRM expressions**, decided expression by expression (:func:`used_expressions`): an expression
   none of whose ARKit inputs names a morph of the avatar (1.0 preset names; 0.x's ``a``, ``joy``,
   ``blink_l``... are translated) takes
   ``clip(sum of weight x ARKit value, 0, 1)`` from :data:`ARKIT_TO_VRM`, and each expression's
   morph binds add ``expression weight x bind weight`` to its morph targets (clipped to [0, 1]).
   ``blink`` is driven only if the avatar lacks ``blinkLeft`` or ``blinkRight`` (else the two
   eyes are driven apart and ``blink`` stays 0, so no eye closes twice).  The avatar's own VRM
   rules (``isBinary``, ``overrideBlink``/``overrideMouth``/``overrideLookAt``) apply to the
   expressions' weights first (:func:`vrm_rules`).
3. **Breathing.**  The body's ``chest`` and ``belly`` channels go to morph targets named
   ``laughlab_chest`` and ``laughlab_belly`` (case ignored; plain ``chest``/``belly`` only on laughlab's
   own mannequin files: on another avatar those are body-shape sliders) if the avatar has them, else to
   the spine bones (:func:`breathing_pose`).

Every morph target none of these sets keeps the avatar's default weight (:func:`morph_weights`), and
:func:`face_route` says in one line which route the face takes and how many morphs it drives.
"""
from __future__ import annotations

import re
import sys
from typing import Mapping

import numpy as np

from laughlab.avatar.load import Avatar
from laughlab.character.body import FACE_MORPHS
from laughlab.motion.skeleton import Skeleton

#: VRM 1.0 expression <- ARKit blendshape weights (linear; the sum is clipped to [0, 1]). ``angry`` is not driven
#: (since 2026-11-29): laughlab's faces lower the brows only in the laugh's squint (``face=facs``' AU4, with the
#: cheeks' AU6), and a VRM avatar's angry preset is a whole face: a facial animator's review saw VRoid avatars laugh
#: with ``angry`` at 0.40-0.57. An avatar with ARKit-named brow morphs still gets ``browDown*``.
ARKIT_TO_VRM: dict[str, dict[str, float]] = {
    "aa": {"jawOpen": 1.0},
    "ih": {"mouthLowerDownLeft": 0.5, "mouthLowerDownRight": 0.5},
    "ou": {"mouthPucker": 1.0},
    "ee": {"mouthStretchLeft": 0.5, "mouthStretchRight": 0.5},
    "oh": {"mouthFunnel": 1.0},
    "happy": {"mouthSmileLeft": 0.5, "mouthSmileRight": 0.5},
    "relaxed": {"cheekSquintLeft": 0.5, "cheekSquintRight": 0.5},
    "sad": {"mouthFrownLeft": 0.5, "mouthFrownRight": 0.5},
    "surprised": {"browInnerUp": 0.5, "browOuterUpLeft": 0.25, "browOuterUpRight": 0.25},
    "blink": {"eyeBlinkLeft": 0.5, "eyeBlinkRight": 0.5},
    "blinkLeft": {"eyeBlinkLeft": 1.0},
    "blinkRight": {"eyeBlinkRight": 1.0},
}

#: every ARKit blendshape name (Apple's ARFaceAnchor.BlendShapeLocation), for recognising morph targets
ARKIT_NAMES: tuple[str, ...] = tuple(sorted(set(FACE_MORPHS) | {
    "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft", "eyeWideLeft", "eyeLookDownRight",
    "eyeLookInRight", "eyeLookOutRight", "eyeLookUpRight", "eyeWideRight", "jawForward", "jawLeft", "jawRight",
    "mouthClose", "mouthFunnel", "mouthPucker", "mouthLeft", "mouthRight", "mouthDimpleLeft", "mouthDimpleRight",
    "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper", "mouthPressLeft",
    "mouthPressRight", "cheekPuff", "noseSneerLeft", "noseSneerRight", "tongueOut"}))
_ARKIT_LOWER = {n.lower(): n for n in ARKIT_NAMES}

#: breathing on the spine bones, degrees of X rotation (x > 0 bends forward) per unit of channel
BREATH_DEGREES: dict[str, dict[str, float]] = {
    "chest": {"spine1": -3.0, "neck": 3.0},   # the rib cage lifts (the chest leans back), the head keeps its gaze
    "belly": {"spine": -2.0, "spine1": 2.0},  # the belly pushes out, the chest stays upright
}


#: ARKit's own spellings of a side (``BlendShapeLocation`` raw values ``eyeBlink_L``, ``mouthSmile_R``; some rigs
#: write ``_Left``/``_Right``), read as Apple's Swift names (``eyeBlinkLeft``)
_SIDE = re.compile(r"_(L|R|Left|Right)$", re.IGNORECASE)


def arkit_morph(name: str) -> str | None:
    """The ARKit blendshape a morph target's name stands for, or None: ``eyeBlinkLeft``, ``eyeBlink_L`` and
    ``eyeBlink_Left`` (ARKit's raw values and a common variant) all stand for ``eyeBlinkLeft``; case and a
    ``prefix.`` are ignored."""
    plain = (name or "").rsplit(".", 1)[-1]
    plain = _SIDE.sub(lambda m: "Left" if m.group(1)[0] in "lL" else "Right", plain)
    return _ARKIT_LOWER.get(plain.lower())


def has_arkit_morphs(avatar: Avatar) -> bool:
    return any(arkit_morph(n) for n in avatar.all_morph_names())


def _binds(avatar: Avatar, expr: str) -> list[tuple[int, int, float]]:
    """The morph binds of an avatar's expression that name a morph target it has."""
    return [(node, index, w) for node, index, w in avatar.expressions.get(expr, [])
            if 0 <= index < len(avatar.morph_names.get(node, ()))]


def used_expressions(avatar: Avatar, channels) -> list[str]:
    """The avatar's VRM expressions the face drives (decided expression by expression): those of
    :data:`ARKIT_TO_VRM` that bind a morph of the avatar and take at least one of ``channels``, none of whose
    ARKit inputs is the name of one of the avatar's morphs (that morph takes its ARKit weight instead).  So a VRM
    with a few ARKit-named morphs beside its presets (partial "perfect sync") still laughs through the others.
    ``blink`` only if the avatar lacks ``blinkLeft`` or ``blinkRight``, else those two."""
    named = {arkit_morph(n) for n in avatar.all_morph_names()} - {None}
    split_eyes = {"blinkLeft", "blinkRight"} <= set(avatar.expressions)
    out = []
    for name, terms in ARKIT_TO_VRM.items():
        if (name == "blink") == split_eyes and name in ("blink", "blinkLeft", "blinkRight"):
            continue
        if _binds(avatar, name) and any(k in channels for k in terms) and not named & set(terms):
            out.append(name)
    return out


def expression_weights(avatar: Avatar | None, arkit: Mapping[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """VRM expression -> weight per frame, from :data:`ARKIT_TO_VRM` (see the module's docstring).

    For an avatar, the expressions :func:`used_expressions` names; ``avatar=None`` (a VRM Animation, which fits
    any VRM): every expression of the table but ``blink`` (the eyes go apart).
    """
    names = ([k for k in ARKIT_TO_VRM if k != "blink"] if avatar is None else used_expressions(avatar, arkit))
    out = {}
    for name in names:
        w = np.zeros(n)
        for k, c in ARKIT_TO_VRM[name].items():
            if k in arkit:
                w = w + c * np.nan_to_num(np.asarray(arkit[k], dtype=np.float64))
        out[name] = np.clip(w, 0.0, 1.0)
    return out


#: VRM 1.0's procedural expressions, by the override property that acts on them (VRMC_vrm-1.0 expressions.md,
#: *Procedural override*)
PROCEDURAL: dict[str, tuple[str, ...]] = {
    "overrideBlink": ("blink", "blinkLeft", "blinkRight"),
    "overrideMouth": ("aa", "ih", "ou", "ee", "oh"),
    "overrideLookAt": ("lookUp", "lookDown", "lookLeft", "lookRight"),
}


def vrm_rules(avatar: Avatar, weights: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Expression weights with the avatar's VRM rules applied, as a VRM player applies them (three-vrm does, on
    this run's ``animation.vrma``), so that the baked file and the VRM Animation agree (VRMC_vrm-1.0
    expressions.md: *expression object*, *Procedural override*, *Interaction between override and isBinary*):

    * ``isBinary``: the weight is 1 above 0.5, else 0;
    * ``overrideBlink``/``overrideMouth``/``overrideLookAt`` of an expression (its output weight ``w``): ``block``
      adds 1 where ``w > 0``, ``blend`` adds ``w``; the procedural expressions of that kind are multiplied by
      ``1 - clip(sum, 0, 1)``, and a binary one among them is 0 wherever that factor is below 1.  An override of
      an expression's own kind (``overrideBlink`` on ``blink``) is ignored, as the specification says.
    """
    rules = avatar.expression_rules
    out = {e: (np.where(w > 0.5, 1.0, 0.0) if rules.get(e, {}).get("isBinary") else w) for e, w in weights.items()}
    for prop, targets in PROCEDURAL.items():
        amount = None
        for e, w in out.items():
            how = rules.get(e, {}).get(prop)
            if how in ("block", "blend") and e not in targets:
                a = (w > 0).astype(np.float64) if how == "block" else w
                amount = a if amount is None else amount + a
        if amount is None:
            continue
        factor = 1.0 - np.clip(amount, 0.0, 1.0)
        for e in targets:
            if e in out:
                out[e] = np.where(factor < 1.0, 0.0, out[e]) if rules.get(e, {}).get("isBinary") else out[e] * factor
    return out


def breath_morph(avatar: Avatar, name: str) -> str | None:
    """The breathing channel (``chest``, ``belly``) a morph target takes, or None: one named ``laughlab_chest`` or
    ``laughlab_belly`` (case ignored); one named plain ``chest`` or ``belly`` only on a file laughlab wrote (its
    mannequin, ``python -m laughlab.avatar.mannequin``; its own character.glb): elsewhere a ``Chest`` morph is
    a character creator's body slider, which breathing drove from 0 to 1 (a review)."""
    low = (name or "").lower()
    if low in ("laughlab_chest", "laughlab_belly"):
        return low[len("laughlab_"):]
    if low in ("chest", "belly"):
        asset = avatar.doc.get("asset") if isinstance(getattr(avatar, "doc", None), dict) else None
        generator = str((asset or {}).get("generator", "")) if isinstance(asset, dict) else ""
        return low if laughlab_made(generator) else None
    return None


#: the generators of the glTF files laughlab makes itself (``laughlab.io.gltf``, ``laughlab.avatar.mannequin``)
OWN_GENERATORS = ("laughlab", "laughlab mannequin")
BAKED = "laughlab (avatar: "


def laughlab_made(generator: str) -> bool:
    """Is a file of this ``asset.generator`` one laughlab made (its mannequin, its character.glb), also once baked
    again (``laughlab (avatar: laughlab mannequin)``)?  A user's avatar baked by laughlab is not (a review: its
    ``Chest`` slider breathed again when its character.glb was loaded)."""
    while generator.startswith(BAKED) and generator.endswith(")"):
        generator = generator[len(BAKED):-1]
    return generator in OWN_GENERATORS


def driven_morphs(avatar: Avatar, arkit: Mapping[str, np.ndarray] | set,
                  breath: Mapping[str, np.ndarray] | set) -> dict[int, list[int]]:
    """Mesh node -> the indices of its morph targets that the run's face and breathing set (the targets
    :func:`morph_weights` computes; every other target keeps the avatar's default weight)."""
    out: dict[int, set[int]] = {}
    for node, names in avatar.morph_names.items():
        for k, name in enumerate(names):
            if arkit_morph(name) in arkit or breath_morph(avatar, name) in breath:
                out.setdefault(node, set()).add(k)
    for expr in used_expressions(avatar, arkit):
        for node, index, _ in _binds(avatar, expr):
            out.setdefault(node, set()).add(index)
    return {node: sorted(ks) for node, ks in sorted(out.items())}


def face_route(avatar: Avatar, channels=FACE_MORPHS) -> dict:
    """How the face drives the avatar, for a face giving ``channels`` (laughlab's faces' ARKit weights by
    default): ``line``, one line saying the route (ARKit-named morphs, VRM expressions, both, or none) and how
    many of its morph targets the face sets; ``morphs_driven``, ``morphs``, ``arkit_morphs`` (counts) and
    ``expressions`` (the VRM expressions used)."""
    face = driven_morphs(avatar, set(channels), set())
    n = sum(len(ks) for ks in face.values())
    total = sum(len(names) for names in avatar.morph_names.values())
    arkit = sum(1 for names in avatar.morph_names.values() for nm in names if arkit_morph(nm) in set(channels))
    exprs = used_expressions(avatar, set(channels))
    how = [f"{arkit} ARKit-named morph{'s' if arkit != 1 else ''}"] if arkit else []
    how += [f"the VRM expression{'s' if len(exprs) != 1 else ''} {', '.join(exprs)}"] if exprs else []
    # with laughlab's faces' channels (the default: the start-up line, said before the run's face has given any),
    # a count for all of them: a run's own face drives fewer (`face=smile`: 7 of Godette's 15, `facs` 9), which
    # character.glb and metrics.json count (a review read "11 of 15" as the run's, against the files' 9)
    up_to = "up to " if set(channels) == set(FACE_MORPHS) and n else ""
    # where the run's own count is (a review looked for it in a gltf run's metrics.json, which has it for a video)
    by = (" by laughlab's faces together (this run's face: counted in metrics.json for a video, in character.glb's "
          "scenes[0].extras.laughlab.face for output=gltf)" if up_to else "")
    line = (f"face: {up_to}{n} of {total} morphs of {avatar.path.name} driven{by}, through {' and '.join(how)}"
            if how else
            f"face: {avatar.path.name} has no morph targets, so its face will not move" if not total else
            f"face: 0 of {total} morphs of {avatar.path.name} driven: no ARKit-named morph and no VRM expression "
            "laughlab maps, so the face will not move (docs/avatars.md)")
    return {"line": line, "morphs_driven": n, "morphs": total, "arkit_morphs": arkit, "expressions": exprs}


_SAID: set = set()


def say_face_route(avatar: Avatar) -> None:
    """Print :func:`face_route`'s line on stderr, once per avatar file (as it is now) in a process: the gltf and
    video sinks of one run, and the stimuli of an experiment, each load the avatar."""
    try:
        st = avatar.path.stat()
        key = (str(avatar.path.resolve()), st.st_mtime_ns, st.st_size)
    except OSError:
        key = (str(avatar.path), 0, 0)
    if key not in _SAID:
        _SAID.add(key)
        print(f"laughlab: {face_route(avatar)['line']}", file=sys.stderr, flush=True)


def morph_weights(avatar: Avatar, arkit: Mapping[str, np.ndarray], breath: Mapping[str, np.ndarray],
                  n: int) -> dict[int, np.ndarray]:
    """Mesh node -> its morph targets' weights per frame ``(F, T)``: the targets :func:`driven_morphs` names
    computed and clipped to [0, 1], every other target at the avatar's default weight
    (:attr:`Avatar.morph_defaults`: a glTF ``weights`` channel sets every target of its node, so a target the
    run does not drive must carry the weight the avatar file gives it, not 0).  Expressions first (their bound
    morphs start at 0 and add up), then ARKit-named morphs and breathing morphs take their channel's weight."""
    driven = driven_morphs(avatar, arkit, breath)
    out = {node: np.zeros((n, len(names))) for node, names in avatar.morph_names.items() if names}
    for expr, w in vrm_rules(avatar, expression_weights(avatar, arkit, n)).items():
        for node, index, weight in _binds(avatar, expr):
            out[node][:, index] += w * weight
    for node, names in avatar.morph_names.items():
        for k, name in enumerate(names):
            a = arkit_morph(name)
            if a is not None and a in arkit:
                out[node][:, k] = arkit[a]
            b = breath_morph(avatar, name)
            if b in breath:
                out[node][:, k] = breath[b]
    for node, w in out.items():
        ks = driven.get(node, [])
        default = np.asarray(avatar.morph_defaults.get(node, np.zeros(w.shape[1])), dtype=np.float64)
        w[:, ks] = np.clip(np.nan_to_num(w[:, ks]), 0.0, 1.0)
        rest = np.setdiff1d(np.arange(w.shape[1]), ks)
        w[:, rest] = default[rest]
    return out


def breath_on_bones(avatar: Avatar, breath: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The breathing channels of ``breath`` that the avatar has no morph for (:func:`breath_morph`): those move
    its spine bones (:func:`breathing_pose`), the others its breathing morphs.  Decided per channel, so an avatar
    with a chest morph and no belly one still breathes with its belly on the bones."""
    names = {breath_morph(avatar, n) for n in avatar.all_morph_names()}
    return {k: v for k, v in breath.items() if k.lower() not in names}


def breathing_pose(poses: np.ndarray, breath: Mapping[str, np.ndarray], skeleton: Skeleton) -> np.ndarray:
    """``poses`` with the breathing of :data:`BREATH_DEGREES` added to the spine joints' X angles."""
    poses = np.array(poses, dtype=np.float64, copy=True)
    for channel, joints in BREATH_DEGREES.items():
        if channel not in breath:
            continue
        w = np.clip(np.nan_to_num(np.asarray(breath[channel], dtype=np.float64)), 0.0, 1.0)
        for joint, deg in joints.items():
            if joint in skeleton.names:
                poses[:, skeleton.angle_slice(joint).start + 1] += deg * w
    return poses
