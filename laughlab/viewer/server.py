"""Serving (or writing) the viewer of a run: the page, three.js, the character, the audio, the channels.

``python -m laughlab view RUN_DIR`` serves on 127.0.0.1 (port 8765, or a free one if that is in
use, printed); ``--out DIR`` writes the same files into a folder that any static host serves.
Nothing comes from a CDN: three.js 0.160.0 (MIT, ``vendor/three/LICENSE``) ships with laughlab,
copied from the npm package ``three`` (``make vendor-three``).

What the page gets from the run directory:

* ``character.glb``: the run's own (``output=gltf``), else built here from ``motion.bvh`` and
  ``channels.csv`` exactly as the ``gltf`` sink builds it; with ``--character PATH`` the user's
  avatar with the run baked in, as ``output=gltf character=PATH`` writes it (a VRM is shown
  through ``@pixiv/three-vrm`` 3.5.5, MIT, ``vendor/three_vrm/LICENSE``: its MToon materials and
  spring bones; ``make vendor-three-vrm``);
* the audio: ``input.wav`` (synthetic input), else the recording named in ``.hydra/config.yaml``;
  without either the page plays on a wall clock;
* ``run.json``: frames per second, duration, the ``mcs`` and ``energy`` channels and the clips
  (start, stop, energy) for the strip under the character.
"""
from __future__ import annotations

import csv
import json
import shlex
import shutil
import socket
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError, first_line
from laughlab.core.summary import VIEWER_NEEDS as NEEDED  # the files a run needs, named once
from laughlab.viewer import page

DEFAULT_PORT = 8765


def _channels(run_dir: Path) -> dict[str, np.ndarray]:
    return _channels_file(run_dir / "channels.csv")


def _channels_file(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    short = next((i + 2 for i, r in enumerate(body) if len(r) != len(head)), None)
    if short is not None:
        raise ValueError(f"line {short} has another number of values than the header (cut short or edited?)")
    out = {}
    for k, name in enumerate(head):
        if name == "label":
            continue
        out[name] = np.array([float(r[k]) if r[k] else np.nan for r in body])
    return out


def _read(path: Path, reader):
    """``reader(path)``, a file of the run that a spreadsheet saved back or a copy cut short turned into one line
    naming it (a review: IndexError and ValueError tracebacks)."""
    try:
        return reader(path)
    except (ValueError, IndexError, KeyError, TypeError, UnicodeDecodeError, csv.Error) as exc:
        why = (f"no column {exc.args[0]!r}" if isinstance(exc, KeyError) and exc.args else
               first_line(exc).replace(f"{path}: ", ""))
        raise LaughlabError(f"{path} is damaged ({why}); run it again to write it whole") from None


def _clips(run_dir: Path, duration: float) -> list[dict]:
    """The played clips (start, stop, energy) from ``events.csv``, paired as the plots pair them."""
    from laughlab.core.frame import ClipEvent, clip_blocks

    with open(run_dir / "events.csv", newline="", encoding="utf-8") as f:
        events = [ClipEvent(float(e["time"]), e["event"], e["clip"], float(e["energy"]))
                  for e in csv.DictReader(f)]
    names = sorted({e.clip for e in events})
    return [{"clip": c, "start": t0, "stop": t1, "energy": e, "index": names.index(c)}
            for c, t0, t1, e in clip_blocks(events, duration)]


def _audio(run_dir: Path, duration: float | None = None) -> Path | None:
    """The run's audio: its ``input.wav``, or the file of an ``input=file`` run (a relative path is taken from the
    folder the run was started in, Hydra's ``runtime.cwd``).  A file that is gone, or whose length is no longer
    the run's (``duration``, s; it was replaced since), is not used: one line on stderr says so, and the page
    plays without sound on the wall clock rather than out of step."""
    if (run_dir / "input.wav").exists():
        return run_dir / "input.wav"
    cfg = run_dir / ".hydra" / "config.yaml"
    if not cfg.exists():
        return None
    import sys

    from omegaconf import OmegaConf

    inp = OmegaConf.load(cfg).get("input") or {}
    path = Path(str(inp.get("path"))).expanduser() if inp.get("name") == "file" and inp.get("path") else None
    if path is None:
        return None
    if not path.is_absolute() and (run_dir / ".hydra" / "hydra.yaml").exists():
        cwd = OmegaConf.load(run_dir / ".hydra" / "hydra.yaml").get("hydra", {}).get("runtime", {}).get("cwd")
        path = Path(str(cwd)) / path if cwd else path
    if not path.is_file():
        print(f"laughlab: the run's audio {path} is gone; the page plays without sound", file=sys.stderr)
        return None
    if duration is not None:
        from laughlab.io.audio import probe_file

        try:
            info = probe_file(path)
            length = info.frames / info.samplerate
        except LaughlabError:   # not readable as audio any more: as if it had changed
            length = float("nan")
        if not abs(length - duration) <= 0.05:
            print(f"laughlab: {path} is not the run's audio any more ({length:.2f} s, the run {duration:.2f} s); "
                  "the page plays without sound", file=sys.stderr)
            return None
    return path


def _avatar_glb(run_dir: Path, character: str | Path, skeleton, motion: np.ndarray, ch: dict, fps: float,
                duration: float):
    """The avatar and its ``.glb`` with the run baked in (the face from ``face_arkit.csv`` if the run wrote it)."""
    from laughlab.avatar.bake import baked_glb
    from laughlab.avatar.channels import face_and_breath
    from laughlab.avatar.load import AvatarError, load_avatar

    try:
        avatar = load_avatar(character)
    except AvatarError as exc:
        raise LaughlabError(str(exc)) from None
    arkit, breath = face_and_breath(ch)
    if (run_dir / "face_arkit.csv").exists():
        arkit = {k: v for k, v in _channels_file(run_dir / "face_arkit.csv").items() if k != "time"}
    n = len(motion)
    return avatar, baked_glb(avatar, skeleton, np.arange(n) / fps, motion, arkit, breath,
                             audio_duration_s=duration, fps=fps)


def _baked_avatar(path: Path):
    """The avatar a run's ``character.glb`` was baked on (``output=gltf character=my.vrm``), so that the page
    shows it as ``view --character`` does (a VRM 0.x faces -Z: it was shown from behind, a review), or None for
    laughlab's mannequin."""
    from laughlab.avatar.load import AvatarError, load_avatar
    from laughlab.io.gltf import read_glb

    try:
        doc, _ = read_glb(path)
        if not str(doc.get("asset", {}).get("generator", "")).startswith("laughlab (avatar:"):
            return None
        return load_avatar(path)
    except (AvatarError, ValueError, KeyError, OSError) as exc:
        raise LaughlabError(f"{path}: cannot read the character baked into the run ({exc})") from None


def view_of(avatar) -> dict:
    """What the page needs to know of an avatar: VRM or not, its facing, its humanoid bones' nodes."""
    if avatar is None:
        return {"vrm": False, "facing": 1, "bones": {}}
    return {"vrm": avatar.kind in ("vrm0", "vrm1"), "facing": int(avatar.facing),
            "turn": float(np.arctan2(avatar.turn[2, 0], avatar.turn[0, 0])),   # radians about Y, to face +Z
            "bones": dict(sorted(avatar.bones.items())), "file": avatar.path.name}


def assets(run_dir: str | Path, character: str | Path | None = None) -> dict[str, bytes | Path]:
    """Every file the page needs, by its URL path: bytes, or a path to send as it is; ``character``: a user's
    avatar to show instead of the mannequin."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise LaughlabError(f"no run directory at {run_dir}")
    missing = [n for n in NEEDED if not (run_dir / n).exists()]
    if missing and (run_dir / "metrics.json").exists():   # a finished run whose outputs wrote no animation files
        raise LaughlabError(f"{run_dir} holds no {', '.join(missing)}: its run wrote no animation files (output=vmc "
                            f"alone streams only); run it with output=[files,vmc] to keep them")
    if missing:
        from laughlab.core.rundir import holder

        pid = holder(run_dir)
        if pid is not None:   # the viewer has no live mode (review-live-2 4)
            raise LaughlabError(f"{run_dir} is a run still going (pid {pid}): the viewer plays a finished run; view "
                                "it when it ends (Ctrl-C ends a live session and keeps it); to watch a run as it "
                                "goes, give it output=[files,viewer] (docs/pipeline.md)")
        shows = sorted(p.name for p in (run_dir / "showcase").iterdir() if (p / "motion.bvh").is_file()) \
            if (run_dir / "showcase").is_dir() else []
        if shows:   # an experiment's folder: its showcase runs are the ones to watch (a first-contact review)
            raise LaughlabError(f"{run_dir} is an experiment, not a run: view one of its showcase runs, e.g. python -m "
                                f"laughlab view {shlex.quote(str(run_dir / 'showcase' / shows[0]))} (conditions: "
                                f"{', '.join(shows)})")
        raise LaughlabError(f"{run_dir} is not a finished run: it has no {', '.join(missing)}")
    from laughlab.io.bvh import read_bvh

    skeleton, motion, frame_time = _read(run_dir / "motion.bvh", read_bvh)
    fps = 1.0 / frame_time  # the BVH's frame time is rounded: metrics.json has the run's own fps
    n = len(motion)
    duration = n / fps
    if (run_dir / "metrics.json").exists():   # and the input's own length (the frames span up to a frame more)
        m = json.loads((run_dir / "metrics.json").read_text(encoding="utf-8"))
        fps = float(m.get("fps", fps))
        duration = float(m.get("duration_s") or n / fps)
    ch = _read(run_dir / "channels.csv", _channels_file)
    files: dict[str, bytes | Path] = {}
    avatar = None
    if character is not None:
        avatar, files["character.glb"] = _avatar_glb(run_dir, character, skeleton, motion, ch, fps, duration)
    elif (run_dir / "character.glb").exists():
        files["character.glb"] = run_dir / "character.glb"
        avatar = _baked_avatar(run_dir / "character.glb")
    else:
        from laughlab.character.body import build, morph_weights
        from laughlab.io.gltf import character_glb

        files["character.glb"] = character_glb(build(skeleton), np.arange(n) / fps, motion,
                                               morph_weights(ch, n), audio_duration_s=duration, fps=fps)
    audio = _audio(run_dir, duration)
    if audio is not None:
        files["audio" + audio.suffix.lower()] = audio
    pick = {k: [round(float(x), 4) if np.isfinite(x) else 0.0 for x in ch[k]] for k in ("mcs", "energy") if k in ch}
    clips = _read(run_dir / "events.csv", lambda _: _clips(run_dir, duration))
    run = {"name": run_dir.resolve().name, "fps": fps, "duration": duration,
           "audio": ("audio" + audio.suffix.lower()) if audio is not None else None, "channels": pick,
           "clips": clips, "energy_max": max([c["energy"] for c in clips] + [max(pick.get("energy", [1.0]))]),
           "avatar": view_of(avatar)}
    files["run.json"] = json.dumps(run, separators=(",", ":")).encode()
    return {**files, **page_files(run["name"])}


def page_files(name: str) -> dict[str, bytes | Path]:
    """The served page, its script and three.js (by URL path), for a run named ``name`` (also the live viewer's)."""
    files: dict[str, bytes | Path] = {"index.html": page.served(name), "viewer.js": page.viewer_js()}
    vendor = page.vendor_dir()
    for f in sorted(vendor.rglob("*")):
        if f.is_file():
            files["vendor/" + f.relative_to(vendor).as_posix()] = f
    return files


#: the files every viewer page written by :func:`write` holds (``--overwrite`` replaces only such a folder)
PAGE_FILES = ("index.html", "run.json", "viewer.js", "character.glb")


def write(run_dir: str | Path, out: str | Path, character: str | Path | None = None, overwrite: bool = False) \
        -> tuple[Path, bool]:
    """Write the viewer's files into ``out`` (a new or empty folder); return it, and whether its page opens
    as a file.  ``character``: a user's avatar to show instead of the mannequin (as :func:`assets`).

    Its ``index.html`` carries three.js (and three-vrm for a VRM), the run and the character inline
    (``laughlab.viewer.page``), so it works opened as a file; the audio stays beside it (a page opened as a
    file may play a sibling file).  Past :data:`laughlab.viewer.page.INLINE_MAX_BYTES` the page loads its
    files instead, and opened as a file it says how to serve the folder.  The separate files are written
    too, for any static web server.
    """
    out = Path(out)
    if out.is_symlink() and out.is_dir():   # a link to a folder: the page goes into that folder (a review)
        out = out.resolve()
    if out.exists() and not out.is_dir():   # a file was "not an empty folder" (a new-user review)
        raise LaughlabError(f"{out} exists and is not a folder; choose another --out")
    foreign = _not_the_pages(out)
    earlier = foreign == []
    if out.exists() and any(out.iterdir()) and not (overwrite and earlier):
        if overwrite and foreign:
            from laughlab.core.errors import shown_names

            raise LaughlabError(f"{out} holds a viewer page and files that are not its ({shown_names(foreign)}); "
                                "--overwrite replaces only a viewer page: move them or choose another --out")
        again = " or add --overwrite to replace the viewer page in it" if earlier else ""
        raise LaughlabError(f"{out} exists and is not an empty folder; choose another --out{again}")
    files = assets(run_dir, character)
    run = json.loads(files["run.json"])
    glb = files["character.glb"]
    glb = glb.read_bytes() if isinstance(glb, Path) else glb
    files["index.html"] = page.static(run["name"], files["run.json"], glb, out.resolve(), Path(run_dir).resolve(),
                                      vrm=run["avatar"]["vrm"])
    # a folder that exists (empty, or an earlier page with --overwrite) is written in place, keeping its owner,
    # permissions and any mount on it (a review: it was deleted and a new one renamed in); the page is made
    # whole in a hidden folder inside it first, so a failure leaves it as it was
    made = not out.exists()
    tmp = (out.with_name(f".{out.name}.part") if made else out / PART)
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        for name, data in files.items():
            dest = tmp / name
            dest.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(data, Path):
                shutil.copyfile(data, dest)
            else:
                dest.write_bytes(data)
        if made:
            tmp.rename(out)
        else:
            _swap_in(out, tmp)
    except OSError as exc:   # the folder named, not the run's (a review: "cannot write RUN: OSError")
        shutil.rmtree(tmp, ignore_errors=True)
        raise LaughlabError(f"cannot write the viewer page into {out}: {exc.strerror or type(exc).__name__}") \
            from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out, page.fits_inline(files["run.json"], glb)


#: inside a folder that exists: the new page being made, and the earlier page while the new one moves in
PART, OLD = ".laughlab-view.part", ".laughlab-view.old"


def _swap_in(out: Path, tmp: Path) -> None:
    """Move the page made in ``tmp`` into ``out`` in place of what is there (an empty folder, or an earlier page):
    the earlier page's files go aside first and come back if the move fails part way (a review: a failure left
    neither page)."""
    aside = out / OLD
    shutil.rmtree(aside, ignore_errors=True)
    aside.mkdir()
    gone, came = [], []
    try:
        for old in [p for p in out.iterdir() if p.name not in (PART, OLD)]:
            old.rename(aside / old.name)
            gone.append(old.name)
        for new in tmp.iterdir():
            new.rename(out / new.name)
            came.append(new.name)
    except BaseException:
        for name in came:
            if (out / name).is_dir():
                shutil.rmtree(out / name)
            else:
                (out / name).unlink()
        for name in gone:
            (aside / name).rename(out / name)
        aside.rmdir()
        raise
    shutil.rmtree(aside)
    tmp.rmdir()


def _not_the_pages(out: Path) -> list[str] | None:
    """The files in ``out`` that a viewer page :func:`write` wrote would not hold (beside its files, the vendored
    scripts as this laughlab has them and the one audio file its ``run.json`` names), ``[]`` for a page and
    nothing else; None if ``out`` holds no page.  (A review: ``--overwrite`` deleted a file of the user's put in
    ``vendor/`` and any ``audio.*``.)"""
    if not (out.is_dir() and all((out / f).is_file() for f in PAGE_FILES)):
        return None
    try:
        audio = json.loads((out / "run.json").read_text(encoding="utf-8")).get("audio")
    except (ValueError, OSError, AttributeError):
        return None
    # the vendored packages' folders (three, three_vrm...): a page of an earlier laughlab holds other files of
    # them (another three.js), which are the page's too (a review)
    packages = {p.name for p in page.vendor_dir().iterdir() if p.is_dir()}
    held = [p.relative_to(out).as_posix() for p in (out / "vendor").rglob("*") if p.is_file()] \
        if (out / "vendor").is_dir() else []
    return sorted(h for h in held if h.split("/")[1] not in packages or h.count("/") < 2) + sorted(
        p.name for p in out.iterdir() if p.name not in (*PAGE_FILES, "vendor", PART, OLD) and p.name != audio)


#: the names a server on this computer alone answers to (``Host``): another name reaching it is a web page's trick
#: (DNS rebinding: a page of another site whose name the attacker points at 127.0.0.1 reads the run)
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")


class _Handler(SimpleHTTPRequestHandler):
    files: dict = {}
    #: what a 404 says is not part of (the study's server says "this study's page": a review read the viewer's words)
    served = "this run's viewer"
    #: a client that sends nothing for this long while its request is read is let go (a security review: 200
    #: half-sent requests held 200 threads, and at the open-files limit the server refused everyone)
    timeout = 60
    #: listening on this computer alone (127.0.0.1, ::1): only its own names are answered (:data:`LOOPBACK_NAMES`)
    loopback = False

    def foreign_host(self) -> bool:
        """Refuse (403) a request naming another host while the server listens on this computer alone."""
        if not self.loopback:
            return False
        host = (self.headers.get("Host") or "").strip().lower()
        name = host[1:host.index("]")] if host.startswith("[") and "]" in host else host.rsplit(":", 1)[0]
        if not host or name in LOOPBACK_NAMES:   # no Host (HTTP/1.0): no browser, no rebinding
            return False
        self.send_error(403, "this server answers to localhost and 127.0.0.1 only")
        return True

    def do_HEAD(self):  # noqa: N802 - http.server's name
        """As GET without the body (SimpleHTTPRequestHandler's own answered from the working folder: a security
        review read the study database's size and time that way)."""
        self._send(head=True)

    def do_GET(self):  # noqa: N802 - http.server's name
        self._send()

    def _send(self, head: bool = False) -> None:
        if self.foreign_host():
            return
        name = self.path.split("?", 1)[0].lstrip("/") or "index.html"
        data = self.files.get(name)
        if data is None:
            self.send_error(404, f"not part of {self.served}")
            return
        body = data.read_bytes() if isinstance(data, Path) else data
        # byte ranges: a browser seeks in audio only when the server answers them (RFC 9110, 14)
        start, end, status = 0, len(body) - 1, 200
        rng = self.headers.get("Range", "")
        if rng.startswith("bytes=") and "," not in rng:
            a, _, b = rng[6:].partition("-")
            try:
                start, end = (int(a), int(b) if b else len(body) - 1) if a else (len(body) - int(b), len(body) - 1)
            except ValueError:
                start, end = 0, len(body) - 1
            if not 0 <= start <= end < len(body):
                self.send_response(416)
                self.send_header("Content-Range", f"bytes */{len(body)}")
                self.end_headers()
                return
            status = 206
        self.send_response(status)
        self.send_header("Content-Type", self.guess_type(name))
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Content-Length", str(end - start + 1))
        if status == 206:
            self.send_header("Content-Range", f"bytes {start}-{end}/{len(body)}")
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        if not head:   # no time limit on the answer (a slow link's video took more than a minute: it was cut off)
            self.connection.settimeout(None)
            self.wfile.write(body[start:end + 1])
            self.connection.settimeout(self.timeout)

    def log_message(self, *args):  # quiet: the command prints its one line
        pass


def server(run_dir: str | Path, port: int = DEFAULT_PORT, character: str | Path | None = None) -> ThreadingHTTPServer:
    """A server of the run's viewer on 127.0.0.1 (``port``, or a free one if it is taken)."""
    return http_server(assets(run_dir, character), port)


def http_server(files: dict, port: int = DEFAULT_PORT, base: type = None, host: str = "127.0.0.1",
                flag: str = "--host ", **attrs) -> ThreadingHTTPServer:
    """A threaded server of ``files`` (URL path -> bytes or a path) with byte ranges, on ``host``:``port``
    (a free port if that one is taken); ``base`` a subclass of the handler adding routes, ``attrs`` its
    class attributes (also used by ``laughlab.study.server``); ``flag``: how the user set the host, for the
    error line (``output.viewer.host=`` for the live viewer)."""
    handler = type("Handler", (base or _Handler,), {"files": files, "loopback": host in LOOPBACK_NAMES, **attrs})
    handler.extensions_map = {**SimpleHTTPRequestHandler.extensions_map, ".js": "text/javascript",
                              ".glb": "model/gltf-binary", ".json": "application/json", ".wav": "audio/wav",
                              ".mp4": "video/mp4", ".css": "text/css"}
    import errno

    from laughlab.core.errors import LaughlabError

    cls = _Server6 if ":" in host else _Server   # an IPv6 address (::1, ::)
    try:
        try:
            return cls((host, port), partial(handler))
        except OSError as exc:
            if isinstance(exc, socket.gaierror) or exc.errno == errno.EADDRNOTAVAIL:
                raise
            return cls((host, 0), partial(handler))  # the port is taken: the system picks one
    except (socket.gaierror, OverflowError) as exc:
        raise LaughlabError(f"cannot listen on {flag}{host}: it is not an address ({exc.args[-1]}); use 127.0.0.1 "
                            "(this computer), 0.0.0.0 (every network) or one of this computer's addresses") from None
    except OSError as exc:
        raise LaughlabError(f"cannot listen on {flag}{host}: {exc.strerror or exc} (not an address of this "
                            "computer?); use 127.0.0.1 (this computer), 0.0.0.0 (every network) or one of "
                            "this computer's addresses") from None


class _Server(ThreadingHTTPServer):
    def handle_error(self, request, client_address):
        """A client that went away while it was answered (a tab closed during a video, Chromium stopped by the
        same Ctrl-C as ``study simulate``) is no error of the server's: socketserver printed its traceback, 20
        lines, before the command's one line (found trying ``study simulate`` with a Ctrl-C to its process
        group, as a terminal sends it). Any other error is printed as before."""
        import sys

        if isinstance(sys.exc_info()[1], (BrokenPipeError, ConnectionResetError, ConnectionAbortedError)):
            return
        super().handle_error(request, client_address)


class _Server6(_Server):
    address_family = socket.AF_INET6


def shown_url(httpd) -> str:
    """``http://HOST:PORT`` to open the server at: 127.0.0.1 (or ::1) when it listens on every network."""
    host, port = httpd.server_address[:2]
    if host in ("0.0.0.0", "", "::"):
        host = "::1" if host == "::" else "127.0.0.1"
    return f"http://[{host}]:{port}" if ":" in host else f"http://{host}:{port}"


def serve_until_interrupted(httpd: ThreadingHTTPServer) -> None:
    """Serve until Ctrl-C (or SIGTERM), then close the socket (``view`` and ``study serve``)."""
    try:
        httpd.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        httpd.server_close()
