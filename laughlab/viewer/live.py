"""The viewer, live (``output=viewer``): a run's frames pushed to the browser page as they are computed.

The page is the one ``python -m laughlab view RUN`` serves, in live mode (``run.json``'s ``live``): instead of
playing the animation baked into ``character.glb`` it applies, frame by frame, the values that animation would
hold (:func:`laughlab.io.gltf.mannequin_tracks`, or :func:`laughlab.avatar.bake.avatar_tracks` on a user's
avatar), sent over Server-Sent Events (``/events``; WHATWG HTML Living Standard, 9.2). Messages: ``layout``
(the tracks, ``[node, path, size]``, when they start or change), a frame (``{"k", "t", "v", "mcs",
"energy"}``: its index, time in s, the tracks' values in order, the strip's two channels, and ``clips``, the
clips that start or stop on it), ``end``.
A page opened late gets the layout, then the frames from then on; a page that cannot keep up loses its oldest
frames (each frame is a whole pose: nothing accumulates).
"""
from __future__ import annotations

import json
import math
import queue
import threading
import time

import numpy as np

from laughlab.viewer.server import _Handler, http_server

#: frames kept for a page that has not read them yet (10 s at 60 fps); older ones are dropped
BACKLOG = 600
#: a comment line this often (s) keeps an idle stream open through proxies
KEEPALIVE_S = 15.0
#: a page whose socket takes nothing for this long (s) is dropped, and its serving thread ends
WRITE_TIMEOUT_S = 60.0


class Tracks:
    """A chunk of frames as the values of the character's animation tracks (``layout`` and ``values``)."""

    def __init__(self, skeleton, avatar=None):
        self.skeleton, self.avatar = skeleton, avatar

    def __call__(self, chunk) -> tuple[list, np.ndarray]:
        """``(layout, values)``: ``[[node, path, size], ...]`` and an ``(n, sum of sizes)`` array."""
        poses = np.nan_to_num(np.asarray(chunk.poses, dtype=np.float64))
        n = len(poses)
        if self.avatar is not None:
            from laughlab.avatar.bake import avatar_tracks
            from laughlab.avatar.channels import face_and_breath

            arkit, breath = face_and_breath(chunk.channels)
            tracks = avatar_tracks(self.avatar, self.skeleton, poses, arkit, breath)
        else:
            from laughlab.character.body import morph_weights
            from laughlab.io.gltf import mannequin_tracks

            tracks = mannequin_tracks(self.skeleton, poses, morph_weights(chunk.channels, n))   # in [0, 1], finite
        columns = [np.asarray(v, dtype=np.float64).reshape(n, -1) for _, _, v in tracks]
        layout = [[int(node), path, int(c.shape[1])] for (node, path, _), c in zip(tracks, columns)]
        return layout, np.concatenate(columns, axis=1) if columns else np.zeros((n, 0))


def frame_message(k: int, t: float, values: np.ndarray, mcs: float, energy: float, events=()) -> str:
    """One frame's event data (JSON; values to 5 decimals, about 0.3 kB for the mannequin); ``events``: the clips
    that start or stop on it (:class:`laughlab.core.frame.ClipEvent`), as ``[kind, clip, energy]``."""
    def num(x: float) -> float:
        return round(float(x), 5) if math.isfinite(x) else 0.0

    v = np.asarray(values, dtype=np.float64)
    msg = {"k": k, "t": round(t, 6), "v": np.where(np.isfinite(v), np.round(v, 5), 0.0).tolist(), "mcs": num(mcs),
           "energy": num(energy)}
    if events:
        msg["clips"] = [[e.kind, e.clip, num(e.energy)] for e in events]
    return json.dumps(msg, separators=(",", ":"))


class LiveServer:
    """Serves the page and its files, and streams events to every page that opened ``/events``."""

    def __init__(self, files: dict, host: str, port: int):
        self.lock = threading.Lock()
        self.clients: list[queue.Queue] = []
        self.layout: str | None = None
        self.pages = 0
        self.opened = threading.Event()
        self.httpd = http_server(files, port, base=_LiveHandler, host=host, flag="output.viewer.host=", live=self)
        self.thread = threading.Thread(target=self.httpd.serve_forever, name="laughlab-viewer", daemon=True)
        self.thread.start()

    def join(self) -> queue.Queue:
        q: queue.Queue = queue.Queue(BACKLOG)
        with self.lock:
            if self.layout is not None:
                q.put_nowait(("layout", self.layout))
            self.clients.append(q)
            self.pages += 1
        self.opened.set()
        return q

    def leave(self, q: queue.Queue) -> None:
        with self.lock:
            if q in self.clients:
                self.clients.remove(q)

    def push(self, event: str, data: str) -> None:
        with self.lock:
            if event == "layout":
                self.layout = data
            for q in self.clients:
                _offer(q, (event, data))

    def close(self, drain_s: float = 2.0) -> None:
        """Send ``end`` to every page, give them up to ``drain_s`` to read what is queued, stop serving."""
        self.push("end", "{}")
        deadline = time.monotonic() + drain_s
        while time.monotonic() < deadline:
            with self.lock:
                if all(q.empty() for q in self.clients):
                    break
            time.sleep(0.02)
        self.stop()

    def stop(self) -> None:
        with self.lock:
            for q in self.clients:   # the stream's end goes in a full queue too (a page's serving thread waited
                _offer(q, None)      # for it until the browser left)
        self.httpd.shutdown()
        self.httpd.server_close()


def _offer(q: queue.Queue, item) -> None:
    """Queue ``item`` for a page; a page that cannot keep up loses its oldest item instead."""
    while True:
        try:
            q.put_nowait(item)
            return
        except queue.Full:
            try:
                q.get_nowait()
            except queue.Empty:
                pass


class _LiveHandler(_Handler):
    live: LiveServer = None

    def do_GET(self):  # noqa: N802 - http.server's name
        if self.path.split("?", 1)[0] != "/events":
            return super().do_GET()
        if self.foreign_host():
            return
        self.send_response(200)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        q = self.live.join()
        self.connection.settimeout(WRITE_TIMEOUT_S)
        try:
            while True:
                try:
                    item = q.get(timeout=KEEPALIVE_S)
                except queue.Empty:
                    self.wfile.write(b": keep-alive\n\n")
                    self.wfile.flush()
                    continue
                if item is None:
                    return
                event, data = item
                head = b"" if event == "frame" else f"event: {event}\n".encode()
                self.wfile.write(head + b"data: " + data.encode() + b"\n\n")
                self.wfile.flush()
                if event == "end":
                    return
        except OSError:   # the page was closed, or read nothing for WRITE_TIMEOUT_S (a frozen tab)
            return
        finally:
            self.live.leave(q)
