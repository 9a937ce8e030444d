"""The VMC sender never blocks the frame loop (review-live 2, 5): a non-blocking socket, datagrams it cannot send
for a passing cause dropped and counted, each kind said once with the address and the cause.  An error that comes
back on every send ends the run in one line (diff-review 7)."""
from __future__ import annotations

import errno
import json
import re
import socket

import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.core.errors import LaughlabError
from laughlab.io import vmc as vmc_io
from laughlab.io.vmc import VmcSender


def test_the_socket_never_blocks_and_may_broadcast():
    s = VmcSender("127.0.0.1", 39539)
    try:
        assert s.sock.getblocking() is False and s.sock.gettimeout() == 0.0
        assert s.sock.getsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST) == 1
        # connected (the kernel then says when nothing listens), so it sends with send(): BSD and macOS refuse
        # sendto() with an address on a connected socket (EISCONN)
        assert s.connected and s.sock.getpeername() == ("127.0.0.1", 39539)
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

    def send(self, data):   # the sender's socket is connected (VmcSender.connected)
        return self.sendto(data, None)

    def close(self):
        pass


ERRORS = [BlockingIOError(errno.EAGAIN, "Resource temporarily unavailable"),
          OSError(errno.ENETUNREACH, "Network is unreachable"),
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
    assert refused > 0 and json.loads((tmp_path / "metrics.json").read_text())["vmc_refused_sends"] == refused
    assert (tmp_path / "channels.csv").exists()
    out = capsys.readouterr()
    lines = out.err.splitlines()
    # one line per kind of error, with the address and the cause; nobody listening (refused): one note, counted
    note = "laughlab: note: output.vmc: nothing listens at 255.255.255.255:39539 (yet): is the receiver running, on "
    assert [x for x in lines if x.startswith(note)] == [note + "this port? The stream goes on"], out.err
    lines = [x for x in lines if not x.startswith(note)]
    assert len(lines) == 4, out.err
    assert all(x.startswith("laughlab: warning: output.vmc: cannot send to 255.255.255.255:39539 (") for x in lines)
    for cause in ("does not take the datagrams as fast", "Network is unreachable", "No route to host",
                  "No buffer space"):
        assert sum(cause in x for x in lines) == 1, (cause, lines)
    assert "cannot write" not in out.err
    assert f"(not paced: as fast as computed, {dropped} datagrams dropped, {refused} sends refused: nothing listened " \
           "there)" in out.out


class Failing:
    """A socket whose every sendto raises ``error``."""

    def __init__(self, error):
        self.error, self.k, self.closed = error, 0, False

    def sendto(self, data, address):
        self.k += 1
        raise self.error

    def send(self, data):
        return self.sendto(data, None)

    def close(self):
        self.closed = True


FATAL = [(errno.EINVAL, "Invalid argument", ""),   # an IPv6 link-local address without its scope id
         (errno.EAFNOSUPPORT, "Address family not supported by protocol", ""),
         (errno.EMSGSIZE, "Message too long", " (a datagram of 1380 bytes: set output.vmc.max_packet_bytes lower, "
                                              "1400 fits Ethernet)"),
         (errno.EBADF, "Bad file descriptor", ""),
         (errno.EACCES, "Permission denied", "")]   # a broadcast address without SO_BROADCAST


@pytest.mark.parametrize("code, cause, hint", FATAL)
def test_an_error_that_comes_back_on_every_send_ends_the_run_in_one_line(tmp_path, monkeypatch, capsys, code, cause,
                                                                          hint):
    """Every datagram was dropped, one warning, and exit 0 with nothing sent (diff-review 7)."""
    cfg = compose_config(["input.duration_s=1.0", "fps=30"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"csv": {}, "vmc": {"host": "127.0.0.1", "port": 39539, "realtime": "off"}}
    pipe = pipeline.build(cfg)
    fake = Failing(OSError(code, cause))
    with_fake(monkeypatch, fake)
    with pytest.raises(LaughlabError) as e:
        pipeline.execute(pipe, tmp_path, {})
    assert str(e.value) == (f"output.vmc: cannot send to 127.0.0.1:39539: {cause}{hint}; the run stops and what it "
                            "wrote is removed")
    assert fake.k == 1 and fake.closed   # the first datagram, no frame at rest after it; the socket closed
    assert list(tmp_path.iterdir()) == [] and capsys.readouterr().err == ""


def with_fake(monkeypatch, fake):
    """Every VmcSender made from now on sends through ``fake``."""
    init = VmcSender.__init__

    def init_with_fake(self, host, port):
        init(self, host, port)
        self.sock.close()
        self.sock = fake

    monkeypatch.setattr(vmc_io.VmcSender, "__init__", init_with_fake)


def test_the_command_says_a_send_that_cannot_work_in_one_line_not_as_the_run_folder(tmp_path, monkeypatch):
    from inprocess import laughlab

    with_fake(monkeypatch, Failing(OSError(errno.EINVAL, "Invalid argument")))
    run = tmp_path / "run"
    p = laughlab("input.duration_s=1", "output=[files,vmc]", "~output.plots", "output.vmc.realtime=off",
                 f"hydra.run.dir={run}")
    assert p.returncode == 2 and p.stderr == ("laughlab: error: output.vmc: cannot send to 127.0.0.1:39539: Invalid "
                                              "argument; the run stops and what it wrote is removed\n"), p.stderr
    assert not run.exists()


def test_an_error_that_cannot_pass_at_the_frame_at_rest_keeps_the_session(tmp_path, monkeypatch, capsys):
    """The frames went out: the frame at rest after them (rest_on_stop), a larger bundle, is not worth the session."""
    cfg = compose_config(["input.duration_s=0.5", "fps=30"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"csv": {}, "vmc": {"host": "127.0.0.1", "port": 39539, "realtime": "off", "report": False}}
    pipe = pipeline.build(cfg)
    fake = Refusing([OSError(errno.EMSGSIZE, "Message too long")])
    fake.sendto = lambda data, address: None   # the frames go out
    with_fake(monkeypatch, fake)
    sink = next(s for s in pipe.sinks if s.name == "vmc")
    rest = sink._send_rest

    def failing_rest():
        fake.sendto = Failing(OSError(errno.EMSGSIZE, "Message too long")).sendto
        rest()

    sink._send_rest = failing_rest
    metrics = pipeline.execute(pipe, tmp_path, {})
    assert metrics["vmc_frames"] == 15 and metrics["vmc_dropped_datagrams"] >= 1
    assert (tmp_path / "channels.csv").exists()
    err = capsys.readouterr().err
    assert err == ("laughlab: warning: output.vmc: cannot send to 127.0.0.1:39539 (Message too long); its datagrams "
                   "are dropped and counted (the vmc line, metrics.json: vmc_dropped_datagrams)\n"), err


def test_a_host_name_that_resolves_to_ipv6_first_is_sent_to_over_ipv4(monkeypatch):
    """``output.vmc.host=localhost`` where the system resolves it to ::1 first (Debian's and Ubuntu's /etc/hosts,
    Windows): VSeeFace, Warudo and EVMC4U listen on IPv4 only, so the stream went to ::1, where nobody listens, and
    UDP said nothing (review-live-2 1).  A name with an IPv4 address goes to it; an IPv6 literal stays IPv6."""
    real = socket.getaddrinfo

    def v6_first(host, port, *a, **kw):
        if host == "localhost":
            return [(socket.AF_INET6, socket.SOCK_DGRAM, 17, "", ("::1", port, 0, 0)),
                    (socket.AF_INET, socket.SOCK_DGRAM, 17, "", ("127.0.0.1", port))]
        return real(host, port, *a, **kw)

    monkeypatch.setattr(socket, "getaddrinfo", v6_first)
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)   # a receiver as VSeeFace's: IPv4, any address
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(5)
    port = receiver.getsockname()[1]
    s = VmcSender("localhost", port)
    try:
        s.send([b"#bundle\0"])
        assert receiver.recvfrom(64)[0] == b"#bundle\0"
        assert s.sock.family == socket.AF_INET
    finally:
        s.close()
        receiver.close()
    if socket.has_ipv6:
        s = VmcSender("::1", port)
        try:
            assert s.sock.family == socket.AF_INET6
        finally:
            s.close()


def test_a_second_ctrl_c_while_easing_back_still_sends_the_frame_at_rest(tmp_path, monkeypatch):
    """A VTuber's review: Ctrl-C, then Ctrl-C again within the 0.25 s of frames easing back to rest, left the avatar
    mid-laugh (smile 0.95, eyes shut, an arm up): the second interrupt stopped the easing and nothing followed."""
    from pythonosc.osc_bundle import OscBundle
    from pythonosc.osc_message import OscMessage

    import laughlab_plugins.sink_vmc as sink_vmc

    cfg = compose_config(["input.duration_s=1.0", "fps=30", "face=facs"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"vmc": {"host": "127.0.0.1", "port": 39539, "realtime": "off", "report": False}}
    pipe = pipeline.build(cfg)
    sent = []
    fake = Refusing([OSError(errno.EMSGSIZE, "unused")])
    fake.sendto = lambda data, address: sent.append(bytes(data))
    with_fake(monkeypatch, fake)
    sink = next(s for s in pipe.sinks if s.name == "vmc")
    rest, sleeps = sink._send_rest, []

    def second_ctrl_c(seconds):
        sleeps.append(seconds)
        if len(sleeps) == 3:   # the third frame on the way back
            raise KeyboardInterrupt

    def easing_interrupted():
        monkeypatch.setattr(sink_vmc.time, "sleep", second_ctrl_c)
        rest()

    sink._send_rest = easing_interrupted
    with pytest.raises(KeyboardInterrupt):
        pipeline.execute(pipe, tmp_path, {})

    def messages(data):
        if data.startswith(b"#bundle"):
            for item in OscBundle(data):
                yield from messages(item.dgram if isinstance(item, OscMessage) else item.dgram)
        else:
            yield OscMessage(data)

    frames = []
    for data in sent:
        for m in messages(data):
            if m.address == "/VMC/Ext/T":
                frames.append({})
            elif m.address == "/VMC/Ext/Blend/Val":
                frames[-1][m.params[0]] = m.params[1]
    assert len(frames) == 30 + 2 + 1   # the run's, two eased back, the frame at rest
    assert max(frames[29].values()) > 0.3 and set(frames[-1]) == set(frames[29])
    assert all(v == 0.0 for v in frames[-1].values())


def test_a_port_nobody_listens_on_is_said_once_and_the_stream_goes_on(tmp_path):
    """A VTuber's review: output.vmc.port=39999 with nothing listening streamed 351 frames to nobody, exit 0, not a
    word.  The socket is connected, so the kernel says so (ICMP port unreachable): one note, the count in the
    closing line, and the run as before."""
    from inprocess import laughlab

    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()   # a port nothing listens on now
    r = laughlab("input.duration_s=0.5", "output=[files,vmc]", "~output.plots", "output.vmc.realtime=off",
                 f"output.vmc.port={port}", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 0, r.stderr
    assert r.stderr == (f"laughlab: note: output.vmc: nothing listens at 127.0.0.1:{port} (yet): is the receiver "
                        "running, on this port? The stream goes on\n"), r.stderr
    refused = re.search(r", (\d+) sends refused: nothing listened there\)", r.stdout)
    assert refused and int(refused[1]) >= 1, r.stdout
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["vmc_frames"] == 30
