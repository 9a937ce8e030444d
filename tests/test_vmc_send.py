"""The VMC sender never blocks the frame loop and never fails the run (review-live 2, 5): a non-blocking socket,
datagrams it cannot send dropped and counted, each kind of send error said once with the address and the cause."""
from __future__ import annotations

import errno
import json
import socket

from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.io.vmc import VmcSender


def test_the_socket_never_blocks_and_may_broadcast():
    s = VmcSender("127.0.0.1", 39539)
    try:
        assert s.sock.getblocking() is False and s.sock.gettimeout() == 0.0
        assert s.sock.getsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST) == 1
    finally:
        s.close()


class Refusing:
    """A socket whose sendto raises the errors of a real one, in turn; every third datagram goes out."""

    def __init__(self, errors):
        self.errors, self.k, self.sent = errors, 0, 0

    def sendto(self, data, address):
        self.k += 1
        if self.k % 3:
            raise self.errors[self.k % len(self.errors)]
        self.sent += 1

    def close(self):
        pass


ERRORS = [BlockingIOError(errno.EAGAIN, "Resource temporarily unavailable"),
          PermissionError(errno.EACCES, "Permission denied"),
          OSError(errno.EHOSTUNREACH, "No route to host"),
          OSError(errno.ENOBUFS, "No buffer space available"),
          ConnectionRefusedError(errno.ECONNREFUSED, "Connection refused")]


def test_send_errors_drop_and_count_the_datagrams_and_the_run_keeps_its_files(tmp_path, monkeypatch, capsys):
    cfg = compose_config(["input.duration_s=1.0", "fps=30"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"csv": {}, "vmc": {"host": "255.255.255.255", "port": 39539, "realtime": "off"}}
    pipe = pipeline.build(cfg)
    vmc = next(s for s in pipe.sinks if s.name == "vmc")
    fake = Refusing(ERRORS)
    opened = vmc.open

    def open_with_fake(run):
        opened(run)
        vmc.sender.sock.close()
        vmc.sender.sock = fake

    monkeypatch.setattr(vmc, "open", open_with_fake)
    metrics = pipeline.execute(pipe, tmp_path, {})
    refused = sum(1 for k in range(1, fake.k + 1) if k % 3 and k % len(ERRORS) == 4)
    dropped = fake.k - fake.sent - refused
    assert metrics["vmc_frames"] == 30 and dropped > 0 and metrics["vmc_dropped_datagrams"] == dropped
    assert json.loads((tmp_path / "metrics.json").read_text())["vmc_dropped_datagrams"] == dropped
    assert (tmp_path / "channels.csv").exists()
    out = capsys.readouterr()
    lines = out.err.splitlines()
    # one line per kind of error, with the address and the cause; nobody listening (refused) is silent
    assert len(lines) == 4, out.err
    assert all(x.startswith("laughlab: warning: output.vmc: cannot send to 255.255.255.255:39539 (") for x in lines)
    for cause in ("does not take the datagrams as fast", "Permission denied", "No route to host", "No buffer space"):
        assert sum(cause in x for x in lines) == 1, (cause, lines)
    assert "cannot write" not in out.err
    assert f"(not paced: as fast as computed, {dropped} datagrams dropped)" in out.out
