"""An avatar's images (its textures): read and checked when the avatar is loaded, carried into ``character.glb``.

A ``.gltf`` names its images by URI (files beside it, or ``data:`` URIs); a ``.glb``/``.vrm`` holds them in
its buffer.  :func:`read_images` reads every image once, when the avatar is loaded, and asks Pillow what it is:
a file that is missing or that Pillow cannot identify is refused in one line naming it (it stopped a video run
half-way with a line about the run's folder, a review found).  :func:`embed_images` puts the bytes of the
images that were not in the buffer into the baked file's buffer (``bufferView`` and ``mimeType``, glTF 2.0,
3.8 *Texture Data*), so ``character.glb`` carries its textures wherever it is copied (a ``.gltf``'s relative URIs
named files the run's folder does not have: the avatar showed white).
"""
from __future__ import annotations

import base64
import binascii
import io
from pathlib import Path
from urllib.parse import unquote

from laughlab.avatar.errors import AvatarError

#: Pillow's format -> the image's MIME type (PNG and JPEG: glTF 2.0 core; WebP: EXT_texture_webp)
MIME = {"PNG": "image/png", "JPEG": "image/jpeg", "WEBP": "image/webp"}
#: the largest image file laughlab reads beside an avatar
MAX_IMAGE_BYTES = 100 * 1024 * 1024


def beside(path: Path, uri: str) -> Path:
    """The file a glTF's relative ``uri`` names, which must lie in the avatar's folder or below it: a URI such as
    ``../../etc/passwd`` would copy any readable file into the exported character and its web page."""
    target = (path.parent / unquote(uri)).resolve()
    if not target.is_relative_to(path.parent.resolve()):
        raise AvatarError(f"{path}: its file {uri!r} lies outside the avatar's folder; laughlab reads only files "
                          "beside the avatar")
    return target


def image_name(doc: dict, index: int) -> str:
    """How a line names image ``index``: its file (the URI decoded), else its name, else ``image N``."""
    img = (doc.get("images") or [])[index]
    uri = img.get("uri") if isinstance(img, dict) else None
    if isinstance(uri, str) and uri and not uri.startswith("data:"):
        return unquote(uri)
    name = img.get("name") if isinstance(img, dict) else None
    return str(name) if name else f"image {index}"


def _bytes(path: Path, doc: dict, binary: bytes, index: int) -> tuple[bytes, bool]:
    """Image ``index``'s bytes, and whether they lie outside the buffer (a file or a data: URI)."""
    img = doc["images"][index]
    name = image_name(doc, index)
    if not isinstance(img, dict):
        raise AvatarError(f"{path}: image {index} is not an object; the file is damaged")
    if "bufferView" in img:   # checked against the buffer by check_structure
        view = doc["bufferViews"][img["bufferView"]]
        start = view.get("byteOffset", 0)
        return binary[start:start + view["byteLength"]], False
    uri = img.get("uri")
    if not isinstance(uri, str) or not uri:
        raise AvatarError(f"{path}: image {index} has neither a uri nor a bufferView; the file is damaged")
    if uri.startswith("data:"):
        try:
            return base64.b64decode(uri.split(",", 1)[1], validate=True), True
        except (IndexError, binascii.Error, ValueError):
            raise AvatarError(f"{path}: its texture {name!r} is a data: URI that is not base64; the file is "
                              "damaged") from None
    target = beside(path, uri)
    try:
        if target.stat().st_size > MAX_IMAGE_BYTES:
            raise AvatarError(f"{path}: its texture {name!r} is over {MAX_IMAGE_BYTES // (1024 * 1024)} MB")
        return target.read_bytes(), True
    except OSError as exc:
        raise AvatarError(f"{path}: its texture {name!r} cannot be read ({exc.strerror or exc}); put it beside "
                          "the avatar, where its uri says") from None


def image_format(path: Path, name: str, data: bytes) -> str:
    """Pillow's name of the image's format (``PNG``, ``JPEG``, ``WEBP``), or one line saying it is not one."""
    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as im:
            fmt = im.format
            im.verify()   # reads the whole file (a PNG's checksums), without decoding the pixels
    except Exception as exc:   # Pillow raises many kinds (OSError, SyntaxError, struct.error...) on a bad file
        raise AvatarError(f"{path}: its texture {name!r} is not an image laughlab can read ({type(exc).__name__}); "
                          "save it as PNG or JPEG") from None
    if fmt not in MIME:
        raise AvatarError(f"{path}: its texture {name!r} is a {fmt} image; glTF textures are PNG or JPEG")
    return fmt


#: the first bytes of a KTX2 file (KHR_texture_basisu): laughlab does not draw those (an avatar requiring the
#: extension is refused), but one offered beside a PNG fallback is carried along unchecked
KTX2 = b"\xabKTX 20\xbb\r\n\x1a\n"


def read_images(path: Path, doc: dict, binary: bytes) -> dict[int, bytes]:
    """Every image checked (:func:`image_format`; KTX2 ones carried along as they are); image index -> bytes for
    those outside the buffer."""
    out = {}
    for i in range(len(doc.get("images") or [])):
        data, outside = _bytes(path, doc, binary, i)
        if not data.startswith(KTX2):
            image_format(path, image_name(doc, i), data)
        if outside:
            out[i] = data
    return out


def embed_images(doc: dict, images: dict[int, bytes], buf) -> None:
    """Move the images read from files or data: URIs (``images``, :func:`read_images`) into ``buf``
    (:class:`laughlab.io.gltf.Buffer`): each gets a buffer view and its MIME type, and loses its ``uri``."""
    from PIL import Image

    for i, data in sorted(images.items()):
        if data.startswith(KTX2):
            mime = "image/ktx2"
        else:
            with Image.open(io.BytesIO(data)) as im:
                mime = MIME[im.format]
        buf.data += b"\0" * (-len(buf.data) % 4)
        buf.views.append({"buffer": 0, "byteOffset": len(buf.data), "byteLength": len(data)})
        buf.data += data
        img = doc["images"][i]
        img.pop("uri", None)
        img["bufferView"] = len(buf.views) - 1
        img["mimeType"] = mime
