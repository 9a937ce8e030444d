"""Humanoid bone names: laughlab's joints, VRM humanoid bones, and the node names of Mixamo, Ready Player Me, Unreal,
Blender's metarig (Rigify) and VRoid.

A VRM file declares its humanoid bones (``VRM.humanoid.humanBones`` in 0.x,
``VRMC_vrm.humanoid.humanBones`` in 1.0), so no name is guessed for it.  A plain glTF/GLB is
recognised by its node names, compared after dropping a ``mixamorig:`` / ``mixamorig_`` prefix
(any ``NAME:`` prefix) and case: :data:`NODE_NAMES` lists, per VRM bone, the names accepted.
"""
from __future__ import annotations

import re

#: laughlab joint -> VRM humanoid bone (VRM 1.0 names; 0.x uses the same ones)
JOINT_TO_VRM: dict[str, str] = {
    "hips": "hips", "spine": "spine", "spine1": "chest", "spine2": "upperChest", "neck": "neck", "head": "head",
    **{f"{s}_{j}": f"{s}{b}" for s in ("left", "right")
       for j, b in (("clavicle", "Shoulder"), ("upper_arm", "UpperArm"), ("forearm", "LowerArm"), ("hand", "Hand"),
                    ("thigh", "UpperLeg"), ("shin", "LowerLeg"), ("foot", "Foot"), ("toe", "Toes"))},
}

#: VRM bones every humanoid must have (VRM 1.0's required set; VRM 0.x also requires chest and neck,
#: but an avatar without them is still driven: see :data:`laughlab.avatar.retarget`)
REQUIRED: tuple[str, ...] = (
    "hips", "spine", "head", "leftUpperArm", "leftLowerArm", "leftHand", "rightUpperArm", "rightLowerArm",
    "rightHand", "leftUpperLeg", "leftLowerLeg", "leftFoot", "rightUpperLeg", "rightLowerLeg", "rightFoot",
)


def _sided(left_right: dict[str, tuple[str, ...]]) -> dict[str, tuple[str, ...]]:
    out = {}
    for bone, names in left_right.items():
        for side, s in (("left", "Left"), ("right", "Right")):
            out[f"{side}{bone}"] = tuple(n.format(S=s, s=s[0], l=side) for n in names)
    return out


#: VRM bone -> node names accepted in a plain glTF (laughlab's own joints as in ``motion.bvh``, Mixamo and Ready
#: Player Me (``LeftArm``, ``LeftUpLeg``...), VRM and Unity names, ``UpperArm_L``/``UpperArm.L`` styles)
NODE_NAMES: dict[str, tuple[str, ...]] = {
    "hips": ("Hips", "hips", "pelvis"),
    "spine": ("Spine", "spine", "spine_01"),
    "chest": ("Spine1", "Chest", "chest", "spine_02"),
    "upperChest": ("Spine2", "UpperChest", "upperChest", "spine_03"),
    "neck": ("Neck", "neck", "neck_01"),
    "head": ("Head", "head"),
    **_sided({
        "Shoulder": ("{l}_clavicle", "{S}Shoulder", "{S}_Shoulder", "Shoulder_{s}", "Shoulder.{s}", "clavicle_{s}"),
        "UpperArm": ("{l}_upper_arm", "{S}Arm", "{S}UpperArm", "{S}_UpperArm", "UpperArm_{s}", "UpperArm.{s}",
                     "upper_arm.{s}"),
        "LowerArm": ("{l}_forearm", "{S}ForeArm", "{S}LowerArm", "{S}_LowerArm", "LowerArm_{s}", "LowerArm.{s}",
                     "forearm.{s}"),
        "Hand": ("{l}_hand", "{S}Hand", "{S}_Hand", "Hand_{s}", "Hand.{s}"),
        "UpperLeg": ("{l}_thigh", "{S}UpLeg", "{S}UpperLeg", "{S}_UpperLeg", "UpperLeg_{s}", "UpperLeg.{s}",
                     "thigh_{s}", "thigh.{s}"),
        "LowerLeg": ("{l}_shin", "{S}Leg", "{S}LowerLeg", "{S}_LowerLeg", "LowerLeg_{s}", "LowerLeg.{s}",
                     "calf_{s}", "shin.{s}"),
        "Foot": ("{l}_foot", "{S}Foot", "{S}_Foot", "Foot_{s}", "Foot.{s}"),
        "Toes": ("{l}_toe", "{S}ToeBase", "{S}Toes", "{S}_Toes", "Toes_{s}", "Toes.{s}", "ball_{s}", "toe.{s}"),
    }),
}

#: the trunk of Blender's human metarig (Rigify), whose root bone ``spine`` is the hips: used instead of the trunk
#: names above when the avatar has a node ``spine.001`` (its spine)
METARIG_TRUNK: dict[str, tuple[str, ...]] = {
    "hips": ("spine",), "spine": ("spine.001",), "chest": ("spine.002",), "upperChest": ("spine.003",),
    "neck": ("spine.004",), "head": ("spine.006", "spine.005"),
}


def plain_name(name: str) -> str:
    """A node name without its ``prefix:`` (``mixamorig:Hips`` -> ``hips``), Rigify's ``DEF-``/``ORG-``/``MCH-``,
    and with VRoid's ``J_Bip_C_``/``J_Bip_L_``/``J_Bip_R_`` read as nothing/``Left``/``Right``
    (``J_Bip_L_UpperArm`` -> ``leftupperarm``), lower case."""
    name = re.sub(r"^mixamorig[0-9]*_", "", name or "")
    name = name.rsplit(":", 1)[-1].strip().lower()
    name = re.sub(r"^(def|org|mch)-", "", name)
    return re.sub(r"^j_bip_([clr])_", lambda m: {"c": "", "l": "left", "r": "right"}[m.group(1)], name)


def bones_by_name(node_names: list[str], rank: list[int] | None = None) -> dict[str, int]:
    """VRM bone -> node index for nodes whose names :data:`NODE_NAMES` knows.  Among nodes of one name, the lowest
    ``rank`` wins, then the first; a node ranked below 0 is never a bone.  :func:`node_ranks` ranks a glTF's nodes
    so that a bone is a skin's joint before a plain node, and a mesh named like a bone (``Head``, ``Body``: many
    game characters) comes last or not at all (a review: a skinned mesh ``Head`` listed first took the head's
    place, and the real head bone never turned)."""
    rank = rank or [0] * len(node_names)
    index: dict[str, int] = {}
    for i, n in enumerate(node_names):
        key = plain_name(n)
        if rank[i] >= 0 and (key not in index or rank[i] < rank[index[key]]):
            index[key] = i
    table = {**NODE_NAMES, **METARIG_TRUNK} if "spine.001" in index else NODE_NAMES
    out = {}
    for bone, names in table.items():
        for n in names:
            i = index.get(n.lower())
            if i is not None:
                out[bone] = i
                break
    return out


def node_ranks(doc: dict) -> list[int]:
    """Each node's rank as a bone for :func:`bones_by_name`: 0 a joint of a skin, 1 a node without a mesh, 2 a
    mesh that is not skinned (a rigid part may be its own bone), -1 a skinned mesh (never: glTF ignores its own
    transform, 2.0 spec 3.7.3 *Skins*)."""
    joints = {j for s in doc.get("skins") or [] for j in s.get("joints") or []}
    return [0 if i in joints else -1 if "skin" in n else 2 if "mesh" in n else 1
            for i, n in enumerate(doc.get("nodes") or [])]
