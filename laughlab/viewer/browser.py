"""Driving the viewer in headless Chromium over the DevTools protocol (what Puppeteer speaks).

Used by the viewer's tests and by ``make docs`` for the README's picture of the viewer:
``python -m laughlab.viewer.browser RUN_DIR OUT.png [--at SECONDS] [--character AVATAR]``.  Needs Debian's
``chromium`` (``make browser``) and the ``websocket-client`` package (the ``test`` extra).
"""
from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
import urllib.request

from laughlab.core.errors import LaughlabError


#: where Chromium-family browsers install themselves on macOS and Windows (a portability review: only Debian's
#: names on the PATH were looked for)
INSTALLED = ("/Applications/Chromium.app/Contents/MacOS/Chromium",
             "/Applications/Google Chrome.app/Contents/MacOS/Google Chrome",
             *(os.path.join(os.environ.get(root, ""), *rel) for root in ("PROGRAMFILES", "PROGRAMFILES(X86)",
                                                                         "LOCALAPPDATA")
               for rel in (("Google", "Chrome", "Application", "chrome.exe"),
                           ("Microsoft", "Edge", "Application", "msedge.exe")) if os.environ.get(root)))


def chromium() -> str:
    """The browser for the headless pages: ``LAUGHLAB_CHROMIUM``, else Chromium or Chrome on the PATH, else where
    macOS and Windows install Chromium, Chrome or Edge."""
    given = os.environ.get("LAUGHLAB_CHROMIUM")
    if given:
        if not os.path.isfile(given):
            raise LaughlabError(f"LAUGHLAB_CHROMIUM={given} is not a file: give the browser's program")
        return given
    exe = next(filter(None, map(shutil.which, ("chromium", "chromium-browser", "google-chrome", "chrome"))), None) \
        or next((path for path in INSTALLED if os.path.isfile(path)), None)
    if exe is None:
        raise LaughlabError("this needs Chromium or Chrome: on Debian make browser (apt-get install chromium); "
                            "elsewhere install Chrome, or set LAUGHLAB_CHROMIUM to a Chromium-family browser's program")
    return exe


def _why(stderr_lines: list[str]) -> str:
    """Chromium's reason for not starting: its first FATAL message (``[pid:tid:time:FATAL:file] text``), else its
    last line of output."""
    line = (next((ln for ln in stderr_lines if ":FATAL:" in ln), None)
            or next((ln for ln in reversed(stderr_lines) if ln), "(no output)"))
    return line.split("] ", 1)[1] if line.startswith("[") and "] " in line else line


class Page:
    """One page of a headless Chromium (software WebGL), its console problems collected."""

    def __init__(self, url: str, width: int = 960, height: int = 720):
        import websocket

        self.profile = tempfile.mkdtemp()
        self.proc = subprocess.Popen(
            [chromium(), "--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
             "--autoplay-policy=no-user-gesture-required", f"--window-size={width},{height}",
             f"--user-data-dir={self.profile}", "--remote-debugging-port=0", "about:blank"],
            stderr=subprocess.PIPE, text=True, start_new_session=True)   # its own group: closed with its children
        port, said = None, []
        for line in self.proc.stderr:
            if "DevTools listening on" in line:
                port = line.strip().rsplit(":", 1)[1].split("/")[0]
                break
            said.append(line.strip())
        if port is None:
            self._stop()
            shutil.rmtree(self.profile, ignore_errors=True)
            raise LaughlabError("chromium did not start its DevTools endpoint: " + _why(said))
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json"))
        page = next(t for t in targets if t["type"] == "page")
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=60)
        self.n, self.events = 0, []
        for domain in ("Runtime", "Log", "Page"):
            self.call(f"{domain}.enable")
        self.call("Page.navigate", url=url)

    def call(self, method: str, **params) -> dict:
        self.n += 1
        self.ws.send(json.dumps({"id": self.n, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.n:
                return msg.get("result", {})
            self.events.append(msg)

    def eval(self, expr: str):
        r = self.call("Runtime.evaluate", expression=expr, awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in r:
            raise LaughlabError(f"page error: {r['exceptionDetails'].get('text')}")
        # no result: the page navigated away while it was evaluated (its context gone); nothing to give
        return r.get("result", {}).get("value")

    def wait_ready(self, timeout_s: float = 60.0) -> None:
        t0 = time.time()
        while not self.eval("!!(window.laughlab && window.laughlab.ready)"):
            if time.time() - t0 > timeout_s:
                raise LaughlabError(f"the viewer did not get ready: {self.problems()}")
            time.sleep(0.2)

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def problems(self) -> list[str]:
        """Console errors and warnings, and uncaught exceptions, so far."""
        out = []
        for e in self.events:
            m, p = e.get("method"), e.get("params", {})
            if m == "Runtime.exceptionThrown" or (m == "Runtime.consoleAPICalled" and p["type"] in ("error", "warning")) \
                    or (m == "Log.entryAdded" and p["entry"]["level"] in ("error", "warning")):
                out.append(json.dumps(p)[:300])
        return out

    def close(self) -> None:
        """Stop Chromium and remove its profile, and the singleton socket folder it keeps in TMPDIR
        (``org.chromium.Chromium.*``, which the profile's ``SingletonSocket`` link points into and which
        Chromium leaves behind whether it is killed or asked to quit)."""
        self.ws.close()
        self._stop()
        try:
            socket_dir = os.path.dirname(os.readlink(os.path.join(self.profile, "SingletonSocket")))
        except OSError:
            socket_dir = ""
        if os.path.basename(socket_dir).startswith("org.chromium.Chromium."):
            shutil.rmtree(socket_dir, ignore_errors=True)
        for _ in range(50):   # a child that was still writing into the profile may add a file while it goes
            shutil.rmtree(self.profile, ignore_errors=True)
            if not os.path.exists(self.profile):
                break
            time.sleep(0.02)

    def _stop(self) -> None:
        """Kill Chromium and every process it started (renderer, GPU, zygote: its process group)."""
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError, AttributeError):   # AttributeError: Windows has no killpg
            self.proc.kill()
        self.proc.wait()


def main(argv: list[str] | None = None) -> None:
    from laughlab.viewer import server as V

    parser = argparse.ArgumentParser(prog="python -m laughlab.viewer.browser",
                                     description="A screenshot of a run's viewer (headless Chromium).")
    parser.add_argument("run_dir")
    parser.add_argument("out", help="PNG file to write")
    parser.add_argument("--at", type=float, default=3.0, help="time to show (s)")
    parser.add_argument("--character", help="a user's avatar to show the run on (VRM, humanoid glTF)")
    ns = parser.parse_args(argv)
    httpd = V.server(ns.run_dir, 0, ns.character)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    page = Page(f"http://127.0.0.1:{httpd.server_address[1]}/")
    try:
        page.wait_ready()
        page.eval(f"window.laughlab.check({ns.at})")
        with open(ns.out, "wb") as f:
            f.write(page.screenshot())
    finally:
        page.close()
        httpd.shutdown()


if __name__ == "__main__":
    main()
