"""Sink ``viewer``: the run on the character in the browser, live, as it is computed.

``python -m laughlab input=mic 'output=[files,viewer]'`` serves the viewer's page (the one ``python -m laughlab
view`` serves for a finished run) at ``http://127.0.0.1:8765/`` and sends it every frame as it is computed: a live
session shows in a browser without a VMC receiver. A file or the synthetic input is paced at the frame clock, and
waits for the page to open (``wait``). The values sent are the ones ``character.glb`` bakes
(:mod:`laughlab.viewer.live`); ``character=PATH`` shows a user's avatar, as ``output=gltf`` bakes it.
"""
from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from typing import Optional

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.core.clock import FramePacer
from laughlab.core.plugins import check_range
from laughlab.core.quiet import to_devnull


@dataclass
class ViewerParams:
    """Parameters of the ``viewer`` sink.

    Attributes
    ----------
    host : str
        Address the page is served on (127.0.0.1: this computer only; 0.0.0.0: every network).
    port : int
        Port (8765, or a free one if it is taken; 0: any free one; the line printed says which).
    realtime : str
        ``auto``: a live source (``input=mic``) is sent as it comes, any other input paced at the frame clock;
        ``on`` / ``off`` force pacing on or off.
    wait : str
        ``auto``: a paced input waits for a page to open before its first frame (a live one does not wait);
        ``on`` / ``off``: always / never wait.
    character : str or None
        A user's avatar to show (the top-level ``character=PATH`` sets it); None: the mannequin.
    """

    host: str = "127.0.0.1"
    port: int = 8765
    realtime: str = "auto"
    wait: str = "auto"
    character: Optional[str] = None

    def __post_init__(self) -> None:
        check_range("port", self.port, 0, 65535)
        for key in ("realtime", "wait"):
            if getattr(self, key) not in ("auto", "on", "off"):
                raise ValueError(f"{key} must be auto, on or off (got {getattr(self, key)!r})")


class ViewerSink(Sink):
    """Serves the live page and sends each frame to it as soon as the pipeline hands it over."""

    name = "viewer"
    Params = ViewerParams
    streaming = True

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        from laughlab.avatar import sink_character

        self.avatar = sink_character(self.params)

    def open(self, run) -> None:
        super().open(run)
        from laughlab.motion.skeleton import rest_pose
        from laughlab.viewer.live import LiveServer, Tracks
        from laughlab.viewer.server import page_files, shown_url, view_of

        p = self.params
        self.tracks = Tracks(run.skeleton, self.avatar)
        live = bool(getattr(run.source, "live", False))
        self.paced = p.realtime == "on" or (p.realtime == "auto" and not live)
        rest = rest_pose(run.skeleton)[None]
        if self.avatar is not None:
            from laughlab.avatar.bake import baked_glb

            glb = baked_glb(self.avatar, run.skeleton, np.zeros(1), rest, {}, {}, 0.0, run.fps)
        else:
            from laughlab.character.body import MORPHS, build
            from laughlab.io.gltf import character_glb

            glb = character_glb(build(run.skeleton), np.zeros(1), rest, np.zeros((1, len(MORPHS))), 0.0, run.fps)
        name = f"live: {run.out_dir.resolve().name}"
        doc = {"name": name, "fps": run.fps, "duration": 0.0, "audio": None, "channels": {}, "clips": [],
               "energy_max": 1.0, "avatar": view_of(self.avatar), "live": True}
        files = {**page_files(name), "character.glb": glb, "run.json": json.dumps(doc).encode()}
        self.server = LiveServer(files, p.host, p.port)
        self.url = shown_url(self.server.httpd) + "/"
        self.n, self.pacer = 0, FramePacer(run.fps)
        self.layout = None
        waits = p.wait == "on" or (p.wait == "auto" and self.paced)
        got = self.server.httpd.server_address[1]   # moved: a page or OBS source on the port asked for sees nothing
        taken = f"port {p.port} is taken (output.viewer.port=PORT for another); " if p.port and got != p.port else ""
        self._say(f"laughlab: {taken}watch it live at {self.url}" + (" (the run starts when the page opens; "
                                                              "output.viewer.wait=off starts at once)" if waits else ""))
        while waits and not self.server.opened.wait(0.1):
            pass

    @staticmethod
    def _say(text: str) -> None:
        try:
            print(text, file=sys.stderr, flush=True)
        except BrokenPipeError:
            to_devnull(sys.stderr.fileno())

    def write(self, chunk) -> None:
        from laughlab.viewer.live import frame_message

        n = len(chunk.times)
        if not n:
            return
        layout, values = self.tracks(chunk)
        if layout != self.layout:
            self.layout = layout
            self.server.push("layout", json.dumps(layout, separators=(",", ":")))
        mcs = np.asarray(chunk.channels.get("mcs", np.zeros(n)), dtype=np.float64).reshape(-1)
        energy = np.asarray(chunk.channels.get("energy", np.zeros(n)), dtype=np.float64).reshape(-1)
        events = chunk.events_by_frame(self.run.fps)
        for i in range(n):
            if self.paced:   # frame k is due (k + 1) / fps after the start, when its audio would have been heard
                self.pacer.wait(self.n)
            self.server.push("frame", frame_message(self.n, float(chunk.times[i]), values[i], mcs[i], energy[i],
                                                      events[i]))
            self.n += 1

    def metrics(self) -> dict:
        return {"viewer_frames": int(getattr(self, "n", 0)), "viewer_pages": int(self.server.pages)
                if getattr(self, "server", None) is not None else 0}

    def close(self):
        self.server.close()
        pages = self.server.pages
        self._say(f"viewer: {self.n} frame{'' if self.n == 1 else 's'} sent to " + ("no page" if not pages else "1 page" if pages == 1 else
                                                          f"{pages} pages") + f" at {self.url}")
        return []

    def abort(self) -> None:
        if getattr(self, "server", None) is not None:
            self.server.stop()


@hookimpl
def register_sinks(register):
    register(ViewerSink)
